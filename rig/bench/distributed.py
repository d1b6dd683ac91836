"""Method studies as dask.distributed tasks: a LocalCluster on this machine, or any scheduler by its address.

A study (`rig bench sampling`) is many independent simulated campaigns; each is a task. Results are gathered
as they finish (`as_completed`), and a finished task may start others (a draw's adaptive runs need its table's
rig time): `run_tasks` keeps one queue for both. A task that raises is reported with its label (the draw and
seed it ran) and its error, and counted: a study never drops a failure silently, and the caller decides what a
failure means for its verdict. dask is an optional dependency (the `bench` extra): it is imported when a study
starts, so that the rest of rig does not need it.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class Task:
    """A function call to run on a worker, and the label that names it in progress lines and failure reports."""

    label: str
    fn: Callable[..., Any]
    args: tuple[Any, ...] = ()
    meta: dict[str, Any] = field(default_factory=dict)
    priority: int = 0       # larger runs first (dask's priority): a study finishes its draws in turn


@dataclass(frozen=True)
class Failure:
    """A task that raised: its label, its meta (the draw and seed, for a study) and the error, as text."""

    label: str
    meta: dict[str, Any]
    error: str


@contextmanager
def study_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Any]:
    """A dask Client: on the scheduler at `scheduler` (host:port or tcp://host:port), else on a LocalCluster of
    `workers` single-threaded worker processes (default one per core), its HTTP endpoints on loopback at a free
    port (no dashboard: bokeh is not a dependency). The cluster is closed on exit, whatever happened."""
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:      # pragma: no cover - the bench extra names it
        raise RuntimeError("method studies need dask.distributed: pip install 'rig[bench]'") from exc
    if scheduler is not None:
        address = scheduler if "://" in scheduler else f"tcp://{scheduler}"
        with Client(address, timeout="30s") as client:
            yield client
        return
    n = workers or os.cpu_count() or 1
    with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                      host="127.0.0.1", silence_logs=logging.ERROR) as cluster, Client(cluster) as client:
        yield client


def workers_of(client: Any) -> int:
    """How many workers the client's scheduler has now."""
    return len(client.scheduler_info(n_workers=-1)["workers"])


def run_tasks(client: Any, tasks: Iterable[Task], then: Callable[[Task, Any], Iterable[Task]] = lambda t, r: (),
              progress: Callable[[str], None] = lambda line: None) -> tuple[list[tuple[Task, Any]], list[Failure]]:
    """Run `tasks` on the client's workers; as each finishes, `then(task, result)` may add tasks. Returns every
    (task, result) in the order they finished and every failure (a task whose successors therefore never ran is
    one failure: its label says which). `progress` gets one line per finished or failed task."""
    from distributed import as_completed

    submitted: dict[str, Task] = {}

    def submit(task: Task) -> Any:
        future = client.submit(task.fn, *task.args, pure=False, priority=task.priority)
        submitted[future.key] = task
        return future

    queue = as_completed([submit(t) for t in tasks])
    done: list[tuple[Task, Any]] = []
    failures: list[Failure] = []
    total = len(submitted)
    for future in queue:
        task = submitted[future.key]
        if future.status != "finished":
            error = future.exception() if future.status == "error" else f"task {future.status}"
            failures.append(Failure(task.label, task.meta, f"{type(error).__name__}: {error}"
                                    if isinstance(error, BaseException) else str(error)))
            progress(f"[{len(done) + len(failures)}/{total}] FAILED {task.label}: {failures[-1].error}")
            continue
        result = future.result()
        done.append((task, result))
        for nxt in then(task, result):
            queue.add(submit(nxt))
            total += 1
        progress(f"[{len(done) + len(failures)}/{total}] {task.label}")
        future.release()
    return done, failures
