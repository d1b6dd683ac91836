"""What a measured dataset says about the BRDF: fits, predictors, validation, road-lighting quantities, plots.

Owns: model fits (`fit`, `fit_search`, the metrics of Spieringhs et al. 2023 in `metrics`), predictors
(`prediction` the interface, `predict` a fitted model or an interpolant, `incidence_views`, `held_out`,
`resampled`, and `smooth_views`, the C¹ reconstruction the Zemax export tabulates from data), the error of a
dataset against a truth (`validation`), the next batch of an adaptive campaign
(`adaptive`), road-lighting quantities (`road`), figures (`plots`) and reading back what rig wrote
(`result_files`). Entry points: `rig fit`, `rig predict`, `rig plot` and the exports that need a predictor
(rig.cli); `adaptive.choose_batch` for rig.session's adaptive sampler.
May import: rig.data, rig.devices, rig.calibration, rig.planning, rig.config, rig.physics, rig.drivers,
rig.core; not rig.acquisition or rig.simulators beside it: it reads datasets, never a rig.
"""
