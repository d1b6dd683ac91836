"""A git worktree of one commit that imports as that commit, for the studies that compare two versions of rig.

Two traps make a worktree on PYTHONPATH run today's code in part (issue 32). rig is installed editable, and its
finder maps `rig.drivers` and `rig.simulators` to this checkout's drivers/ and simulators/ whenever the tree's
rig/ has no such packages: the worktree gets them in rig/ (symlinks to its own drivers/ and simulators/). And the
compiled kernels (`*.so`, built in this checkout, not in git) are missing there, so the numpy fallbacks would run
and differ in the last digits: they are copied in (the kernels of today's build; each is tested equal to its
fallback by tests/test_compiled_kernels.py).
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The installed layout: drivers/ and simulators/ are rig.drivers and rig.simulators.
MAPPED_PACKAGES = ("drivers", "simulators")


@contextmanager
def source_tree(commit: str, where: Path) -> Iterator[Path]:
    """A worktree of `commit` at `where`, importable as that commit with `tree_env`; removed on exit."""
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", "--quiet", str(where), commit],
                   check=True)
    try:
        for package in MAPPED_PACKAGES:
            (where / "rig" / package).symlink_to(Path("..") / package)
        for kernel in (p for folder in ("rig", *MAPPED_PACKAGES) for p in (ROOT / folder).rglob("*.so")):
            target = where / kernel.relative_to(ROOT)
            if target.parent.is_dir():
                shutil.copy(kernel, target)
        yield where
    finally:
        subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(where)], check=True)


def tree_env(tree: Path) -> dict[str, str]:
    """The environment in which `python` imports rig from `tree` (and not this checkout)."""
    return {**os.environ, "PYTHONPATH": str(tree), "PYTHONSAFEPATH": "1"}
