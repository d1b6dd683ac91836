"""docs/architecture.md's path of one point before issue 32, checked against the code of that time (issue 32).

    python benchmarks/architecture_path_before.py [--commit 381cda1]

The page walks one point's path twice, counted by one rule: as the code stands (its first table, which
tests/test_architecture_path.py holds to the code) and as it stood before issue 32 (the table under "How the
count went", commit 381cda1). This checks the second the way the suite checks the first: it makes a git worktree
of that commit, gives it a page whose path section is the "How the count went" part of today's page, and runs
today's test there (the checks that concern one table and its count: every row a call the run makes, every call a
holder of the point's data makes named by a hop or by the test's list of calls that carry none of it, the count
the table's). Prints pytest's verdict; exit status that of pytest. Needs the repository's history (not a shallow
clone) and the development environment's Python.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "architecture.md"
TEST = ROOT / "tests" / "test_architecture_path.py"
PATH_HEADING = "## One point, from the campaign YAML to a row of brdf.csv"
#: The test's checks of one table and its count (the others concern today's filter-wheel path and planted rows).
CHECKS = ("test_the_page_counts_what_its_table_lists", "test_every_hop_of_the_table_is_a_call_the_run_makes",
          "test_every_call_a_holder_makes_is_a_hop_of_the_page", "test_every_counted_module_runs_code_for_the_point")


def page_before(page: str) -> str:
    """A page whose path section is today's "How the count went": its first table is the path before."""
    before = page.split("### How the count went", 1)[1].split("\n## ", 1)[0]
    return f"{PATH_HEADING}\n{before.replace('**Its count:', '**The count:', 1)}"


def check(commit: str, tree: Path) -> int:
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), commit], check=True)
    try:
        # As installed, drivers/ and simulators/ are rig.drivers and rig.simulators; from a source tree on
        # PYTHONPATH the editable install's finder would give today's, so the worktree gets them in rig/.
        for package in ("drivers", "simulators"):
            (tree / "rig" / package).symlink_to(Path("..") / package)
        (tree / "docs" / "architecture.md").write_text(page_before(PAGE.read_text(encoding="utf-8")),
                                                       encoding="utf-8")
        shutil.copy(TEST, tree / "tests" / TEST.name)
        env = {**os.environ, "PYTHONPATH": str(tree), "PYTHONSAFEPATH": "1"}
        return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "0", "-q",
                               f"tests/{TEST.name}", "-k", " or ".join(CHECKS)], cwd=tree, env=env).returncode
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commit", default="381cda1", help="the commit before issue 32 (default: 381cda1)")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}; the path before issue 32 at {args.commit}, checked with today's "
          f"{TEST.relative_to(ROOT)}", flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        return check(args.commit, Path(tmp) / "before")


if __name__ == "__main__":
    sys.exit(main())
