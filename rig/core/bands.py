"""Row bands of an image run on worker threads: how the compiled kernels (the HDR merge, the simulated
camera's) use every CPU. A kernel releases the GIL while it runs over its rows, so threads scale it;
the bands are contiguous, so each thread streams its own part of the frame from memory."""

from __future__ import annotations

import functools
import os
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

#: Images of at least this many pixels are split into one band of rows per CPU; below it the threads'
#: hand-off costs more than they save.
PARALLEL_MIN_PX = 1 << 16


def run_in_bands(rows: Callable[[int, int], object], height: int, width: int) -> None:
    """Call rows(y0, y1) over [0, height): in the caller's thread for an image under PARALLEL_MIN_PX pixels
    (or one CPU), else one band of rows per CPU on the pool's threads, waiting for all of them. An
    exception in a band is raised here."""
    bands = workers() if height * width >= PARALLEL_MIN_PX else 1
    if bands == 1:
        rows(0, height)
        return
    edges = [height * i // bands for i in range(bands + 1)]
    for done in [_pool(os.getpid()).submit(rows, y0, y1) for y0, y1 in zip(edges[:-1], edges[1:]) if y1 > y0]:
        done.result()


def workers() -> int:
    """CPUs this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


@functools.cache
def _pool(pid: int) -> ThreadPoolExecutor:
    """Worker threads, one per CPU; one pool per process (`pid`), so that a forked child makes its own
    instead of waiting on its parent's threads."""
    return ThreadPoolExecutor(workers(), thread_name_prefix=f"rig-bands-{pid}")
