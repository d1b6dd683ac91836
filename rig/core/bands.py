"""Row bands of an image run on worker threads: how the compiled kernels (the HDR merge, the simulated
camera's) use every CPU. A kernel releases the GIL while it runs over its rows, so threads scale it;
the bands are contiguous, so each thread streams its own part of the frame from memory.

`shared` runs independent parts of a job on one of the same threads while the caller does other work (numpy,
which would otherwise leave a CPU idle); the parts' kernels then run in their thread alone.
"""

from __future__ import annotations

import functools
import os
import threading
from collections import deque
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import TypeVar

T = TypeVar("T")

#: Images of at least this many pixels are split into one band of rows per CPU; below it the threads'
#: hand-off costs more than they save.
PARALLEL_MIN_PX = 1 << 16

#: `.background` is set on a worker thread while it runs a `shared` job's parts.
_thread = threading.local()


def run_in_bands(rows: Callable[[int, int], object], height: int, width: int) -> None:
    """Call rows(y0, y1) over [0, height): in the caller's thread for an image under PARALLEL_MIN_PX pixels
    (or one CPU), else one band of rows per CPU, the first in the caller's thread and the others on the
    pool's, waiting for all of them. An
    exception in a band is raised here. In a `shared` job's part, always in its thread: a worker waiting for
    bands queued behind it on its own pool could wait forever."""
    bands = workers() if height * width >= PARALLEL_MIN_PX and not getattr(_thread, "background", False) else 1
    if bands == 1:
        rows(0, height)
        return
    edges = [height * i // bands for i in range(bands + 1)]
    others = [_pool(os.getpid()).submit(rows, y0, y1) for y0, y1 in zip(edges[1:-1], edges[2:]) if y1 > y0]
    try:
        rows(edges[0], edges[1])                               # the first band in the caller's thread
    finally:
        for band in others:
            band.result()


def shared(parts: Sequence[Callable[[], object]], task: Callable[[], T], pixels: int) -> T:
    """task() in the caller's thread while a worker thread runs `parts` (the work of `pixels` pixels) one
    after another; once task() returns, the caller takes the parts not yet started, then waits for the
    worker's last. So the two CPUs finish together whichever side is longer. Returns task()'s result; an
    exception in a part is raised here. Under PARALLEL_MIN_PX pixels (or on one CPU) all runs here.
    """
    queue = deque(parts)

    def run_parts() -> None:
        while queue:
            try:
                part = queue.popleft()
            except IndexError:                                 # the other thread took the last one
                return
            part()
    helper = (_pool(os.getpid()).submit(_as_background, run_parts)
              if pixels >= PARALLEL_MIN_PX and workers() > 1 and len(queue) > 1 else None)
    try:
        result = task()
        run_parts()
    finally:
        if helper is not None:
            helper.result()
    return result


def _as_background(task: Callable[[], T]) -> T:
    _thread.background = True
    try:
        return task()
    finally:
        _thread.background = False


def workers() -> int:
    """CPUs this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


@functools.cache
def _pool(pid: int) -> ThreadPoolExecutor:
    """Worker threads, one per CPU; one pool per process (`pid`), so that a forked child makes its own
    instead of waiting on its parent's threads."""
    return ThreadPoolExecutor(workers(), thread_name_prefix=f"rig-bands-{pid}")
