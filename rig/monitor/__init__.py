"""`rig monitor DIR`: a read-only live web view of a dataset folder (docs/monitor.md).

`folder` follows the folder's files as a run appends to them; `server` serves the page and its JSON.
"""
