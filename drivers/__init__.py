"""rig.drivers: the device interfaces and the drivers of the real instruments (installed as rig.drivers).

Owns: `interfaces` (the abstract devices: Axis, LuminanceCamera, IlluminanceMeter, LampSupply, Attenuator,
RigDevices), `transport` (line framing over pyserial URLs), `retry` (the one retry policy),
`line_instrument` (drivers as command tables, settings confirmed by one declared hook), `registry` (drivers
installed under the entry-point group `rig.drivers`), the drivers (`delta_sm`, `p9710`, `fw102c`, `zaber`,
`modbus_drive` with its maps, `lmk`, `genicam`, `sim_camera`) and `wallclock`. Entry points: the registry's
`driver_class` (rig.devices builds a rig file's devices through it) and `installed_drivers` (`rig devices
--list`).
May import: rig.core only; rig.physics beside it in the same layer is off limits. A driver speaks the
manual's protocol and knows nothing of campaigns or datasets.
"""
