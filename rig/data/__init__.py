"""The dataset folder (contract: docs/dataset.md) and the file formats rig reads and writes.

Owns: `dataset_format` (the contract's names: columns, units, DatasetError, DiskFullError),
`dataset_writer` (DatasetWriter: no completed point is lost), `dataset_reader` (`load`), `append_log`,
`folderlock`, `output_folder`, `images` (EXR), `campaign_runs`; the exports and imports (`export`, `alta`,
`importer`, `radiance`, `radiance_cal`, `materialx`, `zemax`, `rtb`). Entry points: `dataset_reader.load`,
`dataset_writer.DatasetWriter`, `export` (`rig export`), `importer` (`rig import`).
May import: rig.planning, rig.config, rig.physics, rig.drivers, rig.core; not rig.devices or
rig.calibration beside it: it never touches a device.
"""
