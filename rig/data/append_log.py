"""Append-only, line-oriented files whose every line reaches the disk in order (brdf.csv, events.jsonl).

The dataset writer (rig.data.dataset_writer) appends through these; a failed append is undone, so a file never ends
in half a line that later lines would be glued to.
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path


def write_all(fd: int, data: bytes) -> None:
    """os.write until every byte is written (a write may be short); the one low-level write of the dataset
    writer (the disk-full tests inject ENOSPC here)."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


class AppendLog:
    """A line-oriented file whose every line is on disk before append() returns (or, appended with
    `sync_behind`, before the next append starts).

    A failed append (a full disk) is undone by truncating to the previous length, so the file
    never ends in half a line that later lines would be glued to.
    """

    def __init__(self, path: Path):
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, 0o644)
        self._size = os.fstat(self._fd).st_size
        self._syncer: ThreadPoolExecutor | None = None
        self._behind: tuple[Future[None], int] | None = None     # the fsync in flight, the size before its line

    def append(self, line: str, *, sync_behind: bool = False) -> None:
        """Write `line`; fsync it before returning, or with `sync_behind` on a background thread.

        Behind: the line is written before this returns, so a process that is killed loses nothing
        (the kernel holds it), while the fsync (milliseconds on a busy disk) overlaps the caller's next work. Only a
        power cut or a kernel crash during that fsync can lose the line, and nothing written after it: every append
        first waits for the fsync in flight, so what is on disk is always a prefix of what was written. A failed
        background fsync undoes its line and raises here, at the next append (or at `settle`)."""
        self.settle()
        data = line.encode("utf-8")
        try:
            write_all(self._fd, data)
            if not sync_behind:
                os.fsync(self._fd)
        except OSError:
            self._truncate(self._size)
            raise
        if sync_behind:
            if self._syncer is None:
                self._syncer = ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"fsync {self.path.name}")
            self._behind = (self._syncer.submit(os.fsync, self._fd), self._size)
        self._size += len(data)

    def settle(self) -> None:
        """Wait for the fsync in flight, if any; its OSError is raised here after its line was cut off."""
        if self._behind is None:
            return
        sync, size_before = self._behind
        self._behind = None
        try:
            sync.result()
        except OSError:
            self._truncate(size_before)
            self._size = size_before
            raise

    def _truncate(self, size: int) -> None:
        try:
            os.ftruncate(self._fd, size)
        except OSError:
            pass     # nothing better to do; a reader ignores a torn last line

    def close(self) -> None:
        """Close the file after the fsync in flight (whose failure is no longer anyone's to handle)."""
        try:
            self.settle()
        except OSError:
            pass
        if self._syncer is not None:
            self._syncer.shutdown()
            self._syncer = None
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1
