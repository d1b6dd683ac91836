"""A campaign on a rig, simulated or real: opening the rig a command runs on, and an adaptive run's source of
points. Runtime only; the method studies are rig.bench's, the soak the tests' (tests/soak_runs.py).

Owns: `connect` (`open_rig`, `open_campaign_rig`: the built-in simulated rig or the rig file's devices),
`adaptive_sampler` (`sampler_for`: the next batch, from rig.analysis.adaptive), `warmup_estimate` (the
warm-up `rig plan` and `rig run` expect: the simulated lamp replayed, or a real rig's last warm-ups).
May import: rig.acquisition, rig.simulators, rig.analysis and every layer below them; not rig.bench,
rig.monitor, rig.report or rig.cli above it.
"""
