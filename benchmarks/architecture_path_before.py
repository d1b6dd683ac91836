"""docs/architecture.md's path of one point before issue 32, checked against the code of that time (issue 32).

    python benchmarks/architecture_path_before.py [--commit 381cda1]

The page walks one point's path twice, counted by one rule: as the code stands (its first table, which
tests/test_architecture_path.py holds to the code) and as it stood before issue 32 (the table under "How the
count went", commit 381cda1). This checks the second the way the suite checks the first: in a git worktree of
that commit that imports as that commit (benchmarks/source_tree.py), with a page whose path section is the "How
the count went" part of today's page, it runs today's test (the checks that concern one table and its count:
every row a call the run makes, every call a holder of the point's data makes named by a hop or by the test's
list of calls that carry none of it, the count the table's). Prints pytest's verdict; exit status that of
pytest. Needs the repository's history (not a shallow clone) and the development environment's Python.
"""

from __future__ import annotations

import argparse
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from source_tree import ROOT, source_tree, tree_env

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


def check(tree: Path) -> int:
    (tree / "docs" / "architecture.md").write_text(page_before(PAGE.read_text(encoding="utf-8")), encoding="utf-8")
    shutil.copy(TEST, tree / "tests" / TEST.name)
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-n", "0", "-q",
                           f"tests/{TEST.name}", "-k", " or ".join(CHECKS)], cwd=tree, env=tree_env(tree)).returncode


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--commit", default="381cda1", help="the commit before issue 32 (default: 381cda1)")
    args = parser.parse_args()
    print(f"python {sys.version.split()[0]}; the path before issue 32 at {args.commit}, checked with today's "
          f"{TEST.relative_to(ROOT)}", flush=True)
    with tempfile.TemporaryDirectory() as tmp, source_tree(args.commit, Path(tmp) / "before") as tree:
        return check(tree)


if __name__ == "__main__":
    sys.exit(main())
