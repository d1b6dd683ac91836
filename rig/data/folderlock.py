"""One writer per dataset folder: an exclusive `flock` on `<folder>/.lock` for the whole run.

Two `rig run --resume DIR` started at once would both append the missing points
(duplicate rows, two runs interleaved in events.jsonl). The writer therefore takes
an exclusive, non-blocking `fcntl.flock` on the file `.lock` inside the folder
before it writes anything, and keeps it until `close()`. The file holds the
holder's pid and host as text so a refused process can say who has the folder.

Why a stale lock cannot block a resume: a `flock` belongs to the open file
description, and the kernel drops it when the last descriptor closes, which
includes the death of the process for any reason (kill -9, a crash, a power cut
ends everything anyway). A `.lock` file left behind after such a death is just a
file; only a live process holds the lock. The text in it is never trusted to
decide anything, only shown in the refusal message.

The file is never deleted: deleting it while another process has it open but not
yet locked would let two processes lock two different files of the same name.

NFS caveat: on Linux, `flock` on NFS (since 2.6.12) is emulated with POSIX byte-
range locks through the NFS lock manager, so it works between hosts only when the
server supports locking (NFSv4, or NFSv3 with lockd/statd running); with the
`nolock` mount option locks are local to each client and two hosts could both
write. A lock held by a client that crashes is released only when the server
notices (the NFSv4 lease time, typically 90 s). Keep dataset folders on a local
disk while a run writes to them, and copy them to a share afterwards.
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
from pathlib import Path

LOCK_NAME = ".lock"


class FolderLockedError(RuntimeError):
    """Another live process holds the folder's lock; the message names its pid and host."""


class FolderLock:
    """An exclusive lock on a dataset folder, held from `acquire` until `release`."""

    def __init__(self, folder: Path):
        self.path = Path(folder) / LOCK_NAME
        self._fd: int | None = None

    def acquire(self) -> None:
        """Take the lock without waiting; FolderLockedError if another process has it."""
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            holder = _holder(fd)
            os.close(fd)
            if exc.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise FolderLockedError(f"{self.path.parent} is in use by another rig process ({holder}); "
                                        "one writer per dataset folder: wait for it to end, or stop it "
                                        "(nothing was changed)") from None
            raise
        self._fd = fd
        try:
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"pid {os.getpid()} host {socket.gethostname()}\n".encode(), 0)
        except OSError:
            pass     # a full disk: the lock holds anyway, only the holder's name is missing

    def release(self) -> None:
        """Clear the holder's name and drop the lock (idempotent)."""
        if self._fd is None:
            return
        fd, self._fd = self._fd, None
        try:
            os.ftruncate(fd, 0)
        except OSError:
            pass
        os.close(fd)         # closing the last descriptor releases the flock

    @property
    def held(self) -> bool:
        return self._fd is not None


def _holder(fd: int) -> str:
    """`pid N host H` as the holder wrote it, or a note that it has not written it yet."""
    try:
        text = os.pread(fd, 200, 0).decode("utf-8", "replace").strip()
    except OSError:
        text = ""
    return text or "pid and host not written yet"
