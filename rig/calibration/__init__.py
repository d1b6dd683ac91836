"""The calibration procedures of the rig's devices: how a device is measured against a reference to write its
calibration file (docs/camera-calibration.md).

Owns: `radiometric.measure`, the EMVA 1288 radiometric calibration of a raw camera (metering, exposure sweep,
darks, reduction into a rig.config.camera_calibration.CameraCalibration). Entry point: `rig calibrate`
(rig.cli.calibrate), which opens the device, asks the operator and prints.
May import: rig.config, rig.physics, rig.drivers, rig.core (it sits beside rig.data and rig.devices in the
import-linter layers of pyproject.toml); it never connects a rig itself.
"""
