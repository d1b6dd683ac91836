"""A campaign turned into a plan: which points, in which order, by which moves, in how much rig time.

Owns: `points` (what a plan is made of: Plan, PlannedPoint, SkippedPoint, Motors, skip reasons), `table` (a
table campaign's points), `candidates` (an adaptive campaign's domain and first pass), `plan`
(`build_plan`, rig-time estimates), `estimate` (the warm-up a run expects, its rule and sources), `ordering`
(travel-time ordering), `collisions` (forbidden zones).
Entry points: `plan.build_plan`, `candidates.candidate_plan` (`rig plan`, `rig run`).
May import: rig.config, rig.physics, rig.drivers, rig.core. A plan is data: nothing here moves an axis.
"""
