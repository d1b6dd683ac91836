"""Running a campaign on a connected rig: the point loop and everything a run decides while it measures.

Owns: the preflight every run passes (`preflight`, which returns the run, `Prepared`), the one way to run
and resume a campaign (`run`: `run_campaign`, `resume_campaign`; `execute` connects, makes or reopens the
dataset folder and says how the run ended), the engine (`engine.Runner`: moves, capture, E⊥ readings,
rows), capture (raw HDR `capture`, calibrated `calibrated_capture`, chosen once per run by
`capturer.capturer_for`, their interfaces in `capturing`; `metering`, `frames`, and the ND filter wheel
`attenuation`, which wraps the capturer on a rig with one), the lamp's warm-up and watchdog tending,
suspenders (conditions that pause a run), the ledger of measured points and its checkpoints (`ledger.Mark`),
the run's phase (`phase`: phase.json), ETA, progress bar and summary, stop requests and the outcome
(`outcome.ending_of`).
Entry points: `run.run_campaign` / `run.resume_campaign` (what `rig run` and the benches call).
May import: rig.data, rig.devices, rig.calibration, rig.planning, rig.config, rig.physics, rig.drivers,
rig.core (the import-linter layers of pyproject.toml); not rig.simulators or rig.analysis beside it, nor
anything above (rig.session, rig.bench, rig.cli...). Measures a real or a simulated rig alike.
"""
