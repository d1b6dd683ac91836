"""The files a lab writes, validated: campaign files, rig files (geometry, axes, camera, lamp, meter, devices,
forbidden zones) and calibration files, each a pydantic model whose every error names key, value and
what is allowed.

Owns: `files` (the bounded YAML loader, ConfigFileError), `strict` (the base of every model), `campaign`
(`load_campaign`, `check_campaign_for_rig`), `capture` (the capture schema, declared once), `rigfile`
(`load_rig_config`, `simulated_rig`), `rigdevices`, `zones`, `watchdog`, `stated_u` (calibration
uncertainties a rig file states or leaves out), `camera_calibration` and `geometry_calibration` (the
calibration files, read and written).
Entry points: `campaign.load_campaign`, `rigfile.load_rig_config`.
May import: rig.physics, rig.drivers, rig.core; nothing that connects a device or writes a dataset.
"""
