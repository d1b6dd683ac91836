"""Reading the files of a followed dataset folder whatever they hold (rig.monitor.folder interprets them).

The monitor is a long-lived server reading files that anyone able to write the folder may have replaced, so
nothing here may block, grow without bound or mistake one file for another:
- every file is opened non-blocking and read only if it is a regular file (a FIFO or a device put in the
  place of events.jsonl would otherwise hang every request until a writer appears);
- a read takes at most READ_BYTES, a line longer than MAX_LINE_BYTES is reported and skipped, a file read
  whole (the manifest, skipped.csv, `.lock`) may not exceed its limit;
- an append-only file is the same file only if its device, inode, size and first bytes agree with what was
  read before: a folder removed and replaced by a copy can reuse the inode numbers (and be longer), and its
  lines must not be taken as the continuation of the previous run.
"""

from __future__ import annotations

import json
import os
import socket
import stat
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig.data.dataset_format import FORMAT
from rig.data.folderlock import LOCK_NAME
from rig.monitor.records import short_text

#: Longest line followed; rig's longest (a `point_pending` event) is a few kB.
MAX_LINE_BYTES = 1 << 20
#: Most bytes read from one file at one look; the rest comes at the next look (a viewer's first look at an
#: overnight run catches up in a few looks instead of allocating the whole file at once).
READ_BYTES = 16 << 20
#: Bytes from the start of an append-only file compared at each look to tell a rewritten or copied file.
HEAD_BYTES = 4096
#: Largest dataset.json and skipped.csv read (both are replaced whole by the writer; a paper campaign's are
#: tens of kB); `.lock` holds one line.
WHOLE_FILE_BYTES, LOCK_BYTES = 64 << 20, 256
#: Deepest nesting of lists and objects accepted in JSON read; rig's go 6 deep (the manifest's campaign).
MAX_DEPTH = 64
_KINDS = {stat.S_IFIFO: "a FIFO", stat.S_IFCHR: "a character device", stat.S_IFBLK: "a block device",
          stat.S_IFSOCK: "a socket", stat.S_IFDIR: "a folder", stat.S_IFLNK: "a symbolic link"}


class FollowError(Exception):
    """A followed file that cannot be read (not a regular file, too large, unreadable): the message names it."""


class Replaced(Exception):
    """A followed file is not the one read so far: start over."""


def open_regular(path: Path) -> tuple[int, os.stat_result]:
    """A read-only descriptor of `path` and its status, if it is a regular file: FileNotFoundError if absent,
    FollowError otherwise. O_NONBLOCK makes opening a FIFO return at once instead of waiting for a writer."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    except (FileNotFoundError, NotADirectoryError):
        raise FileNotFoundError(path) from None
    except OSError as exc:
        raise FollowError(f"{path.name}: {exc.strerror or exc}") from None
    st = os.fstat(fd)
    if not stat.S_ISREG(st.st_mode):
        os.close(fd)
        raise FollowError(f"{path.name}: {_KINDS.get(stat.S_IFMT(st.st_mode), 'not a regular file')}, not a file: "
                          "not read")
    return fd, st


def read_whole(path: Path, limit: int) -> bytes | None:
    """A small file replaced atomically by its writer, whole; None if absent, FollowError if larger than `limit`."""
    try:
        fd, st = open_regular(path)
    except FileNotFoundError:
        return None
    try:
        if st.st_size > limit:
            raise FollowError(f"{path.name}: {st.st_size} bytes, more than the {limit} expected: not read")
        return os.pread(fd, limit + 1, 0)[:limit]
    finally:
        os.close(fd)


def _finite(text: str) -> float:
    x = float(text)
    if x - x != 0:                                  # inf and nan: 1e999 parses as inf
        raise ValueError(f"number out of range: {text[:20]}")
    return x


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _nested_within(value: Any, limit: int) -> bool:
    """Whether `value`'s lists and objects are nested at most `limit` deep (iteratively: no recursion)."""
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else None
        if children is None:
            continue
        if depth > limit:
            return False
        stack.extend((child, depth + 1) for child in children)
    return True


def strict_json(text: str | bytes) -> Any:
    """JSON as rig writes it (json.dumps with allow_nan=False, a few levels deep): NaN, Infinity, numbers beyond
    a float and nesting deeper than MAX_DEPTH are refused, so that nothing read can make the monitor's own JSON
    invalid or a later str()/json.dumps() of it recurse too deep. ValueError for anything else (integers beyond
    Python's 4300 digits included), with the reason."""
    try:
        value = json.loads(text, parse_float=_finite, parse_constant=_no_constant)
    except RecursionError:
        raise ValueError("nested too deeply") from None
    if not _nested_within(value, MAX_DEPTH):
        raise ValueError(f"nested deeper than {MAX_DEPTH} levels")
    return value


@dataclass
class Tail:
    """An append-only file read from where the previous read stopped, complete lines only."""

    path: Path
    offset: int = 0
    lines: int = 0                                        # lines consumed so far (numbering for messages)
    identity: tuple[int, int] | None = None              # (device, inode)
    head: bytes = b""                                     # the file's first bytes as read before
    skipping: bool = False                                # inside a line longer than MAX_LINE_BYTES

    def new_lines(self) -> list[tuple[int, bytes | None]]:
        """(line number, bytes without the newline) of the lines completed since the last call, None for a line
        longer than MAX_LINE_BYTES; [] while the file is absent. Replaced if it is not the file read so far,
        FollowError if it cannot be read."""
        try:
            fd, st = open_regular(self.path)
        except FileNotFoundError:
            if self.identity is not None:
                raise Replaced(self.path) from None
            return []
        try:
            identity = (st.st_dev, st.st_ino)
            if self.identity is not None and (identity != self.identity or st.st_size < self.offset):
                raise Replaced(self.path)
            if len(self.head) < HEAD_BYTES:
                start = os.pread(fd, HEAD_BYTES, 0)
                if not start.startswith(self.head):
                    raise Replaced(self.path)
                self.head = start
            elif os.pread(fd, HEAD_BYTES, 0) != self.head:
                raise Replaced(self.path)
            data = os.pread(fd, READ_BYTES, self.offset)
        finally:
            os.close(fd)
        self.identity = identity
        return self._split(data)

    def _split(self, data: bytes) -> list[tuple[int, bytes | None]]:
        found: list[tuple[int, bytes | None]] = []
        keep = data.rfind(b"\n") + 1
        if keep == 0:
            if len(data) >= MAX_LINE_BYTES:             # no end in sight: report it once, drop it to its end
                if not self.skipping:
                    self.lines += 1
                    found.append((self.lines, None))
                self.skipping = True
                self.offset += len(data)
            return found
        for line in data[:keep].split(b"\n")[:-1]:
            if self.skipping:                           # the end of a line already reported
                self.skipping = False
                continue
            self.lines += 1
            found.append((self.lines, None if len(line) > MAX_LINE_BYTES else line))
        self.offset += keep
        return found


def parse_manifest(data: bytes) -> dict[str, Any]:
    """dataset.json's bytes as the manifest (docs/dataset.md); FollowError naming the file and the reason."""
    try:
        manifest = strict_json(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise FollowError(f"dataset.json: not UTF-8 text (byte {exc.start})") from None
    except ValueError as exc:
        raise FollowError(f"dataset.json: not valid JSON ({short_text(str(exc).splitlines()[0])})") from None
    if not isinstance(manifest, dict):
        raise FollowError(f"dataset.json: a JSON {type(manifest).__name__}, not the manifest's object")
    if manifest.get("format") != FORMAT:
        raise FollowError(f"dataset.json: format is {short_text(str(manifest.get('format')), 40)!r}, not {FORMAT!r}")
    return manifest


def writer_alive(folder: Path) -> bool | None:
    """Whether the process named in `.lock` (rig/data/folderlock.py: "pid N host H" while a writer holds it,
    left there by a writer that was killed) is running; None when it cannot be told (no name in the file,
    another host)."""
    try:
        text = (read_whole(folder / LOCK_NAME, LOCK_BYTES) or b"").decode("utf-8", "replace").split()
    except FollowError:
        return None
    if len(text) < 4 or text[0] != "pid" or text[2] != "host" or not (text[1].isascii() and text[1].isdigit()) \
            or len(text[1]) > 10 or not 0 < int(text[1]) < 1 << 31:
        return None
    if text[3] != socket.gethostname():
        return None
    try:
        os.kill(int(text[1]), 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True          # someone else's process: it exists
    return True
