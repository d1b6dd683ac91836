"""Dump what the fault and stop scenarios write, as one commit of rig writes it (issue 32).

    python benchmarks/scenario_dump_at.py COMMIT OUT [pytest paths ...]

Runs the scenarios (by default tests/acquisition and tests/cli/test_end_to_end.py) in a worktree of COMMIT that
imports as COMMIT (benchmarks/source_tree.py), with today's tests/scenario_dump.py plugin keeping each test's
files and output under OUT. Compare two such dumps with benchmarks/scenario_identity.py. Prints where rig.drivers
and rig.simulators were imported from, then pytest's summary; exit status that of pytest.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from source_tree import ROOT, source_tree, tree_env

SCENARIOS = ("tests/acquisition", "tests/cli/test_end_to_end.py")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("commit")
    parser.add_argument("out", type=Path)
    parser.add_argument("paths", nargs="*", default=list(SCENARIOS))
    args = parser.parse_args()
    out = args.out.resolve()
    with tempfile.TemporaryDirectory() as tmp, source_tree(args.commit, Path(tmp) / "tree") as tree:
        shutil.copy(ROOT / "tests" / "scenario_dump.py", tree / "tests" / "scenario_dump.py")
        env = {**tree_env(tree), "RIG_SCENARIO_DUMP": str(out)}
        where = "import rig.drivers as d, rig.simulators as s; print(d.__file__, s.__file__)"
        subprocess.run([sys.executable, "-c", where], cwd=tree, env=env, check=True)
        return subprocess.run([sys.executable, "-m", "pytest", "-p", "scenario_dump", "-p", "no:cacheprovider",
                               "-n", "0", "-q", *args.paths], cwd=tree, env=env).returncode


if __name__ == "__main__":
    sys.exit(main())
