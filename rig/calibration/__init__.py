"""The calibration procedures of the rig's devices: how a device or the goniometer is measured against a
reference to write its calibration file (docs/camera-calibration.md, docs/geometry-calibration.md).

Owns: `radiometric.measure`, the EMVA 1288 radiometric calibration of a raw camera (metering, exposure sweep,
darks, reduction into a rig.config.camera_calibration.CameraCalibration); `geometry`, the ChArUco
calibration of the goniometer (board and lamp views, intrinsics, the model fit of rig.physics.goniometer_fit
into a rig.config.geometry_calibration.GeometryCalibration). Entry point: `rig calibrate camera|geometry`
(rig.cli.calibrate), which opens the devices, asks the operator and prints.
May import: rig.planning, rig.config, rig.physics, rig.drivers, rig.core (it sits beside rig.data and
rig.devices in the import-linter layers of pyproject.toml); it never opens a rig itself: the caller hands in
the devices.
"""
