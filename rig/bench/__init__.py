"""Method studies that `rig bench` runs on the simulated rig: what a capture setting or a sampling strategy
costs in rig time and gains in BRDF error. Apart from the runtime (rig.acquisition, rig.session): nothing
in a measurement imports it.

Owns: `error_vs_time` (BRDF error against rig time per capture setting), `sampling` and `sampling_report`
(per sampling strategy, on drawn samples), `draws` (the simulated samples nobody tuned for), `distributed`
(the studies as dask tasks). Entry point: `rig bench` (rig.cli.bench).
May import: rig.session and every layer below it (rig.acquisition, rig.simulators, rig.analysis, rig.data,
...); not rig.monitor or rig.report beside it, nor rig.cli.
"""
