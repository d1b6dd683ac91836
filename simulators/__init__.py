"""rig.simulators: the built-in simulated rig (installed as rig.simulators): a world that is physically true,
and protocol peers that speak each instrument's wire protocol, so that the real drivers run against it.

Owns: `clock` (SimClock: rig time), `world`, `lamp`, `camera`, `sensor`, `texture` (their full-frame loops
also in C), `axis_model`, the peers (`line_peer` base, `delta_sm_peer`, `p9710_peer`, `fw102c_peer`,
`zaber_peer`, `oriental_az_peer`, `camera_server`), `faults`, `rig` (SimulatedRig) and `served`
(`rig sim serve`). Entry points: `rig.SimulatedRig` (rig.session.connect), `served` (`rig sim serve`).
May import: rig.data, rig.devices, rig.calibration, rig.planning, rig.config, rig.physics, rig.drivers,
rig.core; not rig.acquisition or rig.analysis beside it.
"""
