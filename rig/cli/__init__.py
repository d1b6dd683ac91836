"""The `rig` command line: one module per subcommand, each parsing its arguments, calling the library and
printing; no measurement or analysis logic lives here.

Owns: `main` (`rig`, `rig run`, `rig plan`, `rig devices`; the console script `rig = rig.cli.main:main`),
and `fit`, `export`, `import_alta`, `predict`, `plot`, `report`, `monitor`, `bench`, `sim`, `calibrate`,
each registering its subcommand with `add_subcommand`. Exit codes and the one-line error: rig.core.exits.
May import: every package of rig (the top layer); nothing imports it.
"""
