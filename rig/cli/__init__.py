"""The `rig` command line: one module per subcommand, each parsing its arguments, calling the library and
printing; no measurement or analysis logic lives here.

Owns: `main` (`rig`, `rig run`, `rig plan`, `rig devices`; the console script `rig = rig.cli.main:main`),
and `fit`, `export`, `import_alta`, `predict`, `plot`, `report`, `monitor`, `bench`, `sim`, `calibrate`,
each registering its subcommand with `add_subcommand`. Exit codes and the one-line error: rig.core.exits.
One exception, for now: `zemax_source`, the reconstruction the Zemax export tabulates from data (`rig predict`'s
with a C¹ cubic within each incidence; issue 37), which belongs in rig.analysis and moves there when that
package's interpolant can take it.
May import: every package of rig (the top layer); nothing imports it.
"""
