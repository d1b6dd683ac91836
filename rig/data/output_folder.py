"""A new output folder: never written over, removed when the command that makes it fails; its size on disk."""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import datetime
from pathlib import Path

from rig.core.events import PHASE_FILE
from rig.data.dataset_format import DatasetError
from rig.data.folderlock import LOCK_NAME

#: Bytes set aside in `.reserve` when a writer opens a folder, freed when the disk fills so that
#: the final events and the manifest (about 10 kB, written twice by the atomic replace) still fit.
RESERVE_BYTES = 64 * 1024
RESERVE_NAME = ".reserve"


def require_new_output(path: Path, hint: str = "choose another --out, or continue it with --resume") -> None:
    """DatasetError unless `path` is absent or an empty folder: rig never writes over anything."""
    if not path.exists():
        return
    if not path.is_dir():
        raise DatasetError(f"output {path} exists and is not a folder; choose another --out "
                           "(nothing was overwritten)")
    try:
        occupied = any(p.name != LOCK_NAME for p in path.iterdir())
    except OSError as exc:
        raise DatasetError(f"output folder {path} cannot be read: {exc.strerror or exc}") from None
    if occupied:
        raise DatasetError(f"output folder {path} already exists and is not empty; {hint} (nothing was overwritten)")


def default_output(base: Path, now: datetime | None = None) -> Path:
    """The folder a command writes to when no --out is given: `base` (the campaign's output.dir) while it is free
    (absent, or an empty folder), else `base-YYYYMMDD-HHMMSS` (local time), with `-2`, `-3`, … should that be taken
    too: a second `rig run campaigns/quick.yaml` measures again instead of refusing, and overwrites nothing."""
    try:
        require_new_output(base)
        return base
    except DatasetError:
        pass
    stamped = base.with_name(f"{base.name}-{(now or datetime.now()).strftime('%Y%m%d-%H%M%S')}")
    candidate, k = stamped, 1
    while candidate.exists() or candidate.is_symlink():
        k += 1
        candidate = stamped.with_name(f"{stamped.name}-{k}")
    return candidate


@contextmanager
def removed_on_failure(path: Path) -> Iterator[Path]:
    """Run the body that writes the new output `path`; if it fails, remove what it wrote, so a
    refused or failed command leaves nothing behind. `path` must be absent or an empty folder."""
    existed = path.exists()
    try:
        yield path
    except BaseException:
        if not existed and path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        elif not existed:
            path.unlink(missing_ok=True)
        elif path.is_dir():
            for child in path.iterdir():
                if child.is_dir():
                    shutil.rmtree(child, ignore_errors=True)
                else:
                    child.unlink(missing_ok=True)
        raise


#: What a file being written is called until it is complete: hidden, next to its final name, with the writer's pid.
TEMP_SUFFIX = ".rig-partial"


@contextmanager
def new_file(path: Path) -> Iterator[Path]:
    """Run the body that writes the file `path` under a temporary name next to it; once the body is done, give
    the file its name in one step (a hard link: FileExistsError if `path` appeared meanwhile, nothing is written
    over). A kill leaves at most the hidden temporary file, never a `path` cut short; any failure, an interrupt
    included, removes the temporary file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}{TEMP_SUFFIX}")
    try:
        yield tmp
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        try:
            os.link(tmp, path)
        except FileExistsError:
            raise
        except OSError:              # a file system without hard links: rename, after checking again
            if path.exists():
                raise FileExistsError(17, "File exists", str(path)) from None
            os.rename(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def new_folder(path: Path) -> Iterator[Path]:
    """Run the body that fills the new folder `path` in a temporary folder next to it; once the body is done,
    rename it to `path` in one step (`path` absent or an empty folder, which the rename replaces: OSError if
    anything appeared in it meanwhile). A kill leaves at most the hidden temporary folder, never a `path` half
    full that a rerun would refuse; any failure, an interrupt included, removes the temporary folder."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}{TEMP_SUFFIX}")
    tmp.parent.mkdir(parents=True, exist_ok=True)
    try:
        tmp.mkdir()
        yield tmp
        os.rename(tmp, path)
    finally:
        if tmp.is_dir():
            shutil.rmtree(tmp, ignore_errors=True)


def format_bytes(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB"):
        if abs(n) < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError("unreachable")


def folder_size(folder: Path) -> int:
    """Bytes in the files of `folder` and its sub-folders (images/), the working files left out: the lock, the
    reserve and the run's phase (rig.acquisition.phase: a few bytes replaced as the run goes, not the dataset's)."""
    total = 0
    for root, _, files in os.walk(folder):
        for name in files:
            if name not in (LOCK_NAME, RESERVE_NAME, PHASE_FILE, PHASE_FILE + ".tmp"):
                try:
                    total += os.stat(os.path.join(root, name)).st_size
                except OSError:
                    pass
    return total


def first_missing(path: Path) -> Path | None:
    """The outermost folder of `path` that does not exist yet (what mkdir(parents=True) creates)."""
    missing = None
    for p in (path, *path.parents):
        if p.exists():
            break
        missing = p
    return missing


def existing_parent(path: Path) -> Path:
    """`path` or its nearest existing parent (where free space is measured before a folder exists)."""
    for p in (path, *path.absolute().parents):
        if p.exists():
            return p
    return Path("/")
