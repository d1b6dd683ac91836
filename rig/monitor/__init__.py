"""`rig monitor DIR`: a read-only live web view of a dataset folder (docs/monitor.md).

Owns: `folder` (follows the folder's files as a run appends to them, without changing or locking it),
`files` (reading them whatever they hold), `records` (what the page shows of a row, an event, the plan),
`phase` (the run's phase from the phase.json the engine writes),
`server` and `front` (the HTTP server over bounded connections) and the page in static/. Entry point:
`rig monitor` (rig.cli.monitor).
May import: rig.session and every layer below it; not rig.report or rig.bench beside it, nor rig.cli.
It reads a dataset folder, never a rig.
"""
