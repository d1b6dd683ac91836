"""rig.core.bands: row bands on worker threads, and tasks in the background."""

import threading

import pytest

from rig.core import bands
from rig.core.bands import PARALLEL_MIN_PX, in_background, run_in_bands


def covered(height, width):
    """The (y0, y1) bands run_in_bands calls for an image, and the threads they ran on."""
    calls, threads = [], set()

    def rows(y0, y1):
        calls.append((y0, y1))
        threads.add(threading.current_thread().name)
    run_in_bands(rows, height, width)
    return sorted(calls), threads


def test_a_small_image_is_one_band_in_the_callers_thread():
    calls, threads = covered(3, 5)
    assert calls == [(0, 3)] and threads == {threading.current_thread().name}


@pytest.mark.parametrize("cpus", [1, 2, 3, 7])
def test_a_large_image_is_one_band_per_cpu_covering_every_row_once(monkeypatch, cpus):
    monkeypatch.setattr(bands, "workers", lambda: cpus)
    height = PARALLEL_MIN_PX // 100 + 5
    calls, _ = covered(height, 100)
    rows = [y for y0, y1 in calls for y in range(y0, y1)]
    assert rows == list(range(height)) and len(calls) == min(cpus, height)


def test_an_exception_in_a_band_is_raised_to_the_caller(monkeypatch):
    monkeypatch.setattr(bands, "workers", lambda: 2)

    def rows(y0, y1):
        if y0 > 0:
            raise ValueError("second band")
    with pytest.raises(ValueError, match="second band"):
        run_in_bands(rows, PARALLEL_MIN_PX, 1)


def test_a_background_task_runs_on_a_worker_and_its_bands_in_that_thread():
    """A worker waiting on bands queued behind it on its own pool could wait forever: inside a background
    task run_in_bands keeps to the task's thread."""
    here = threading.current_thread().name
    task = in_background(lambda: (threading.current_thread().name, covered(PARALLEL_MIN_PX, 2)), PARALLEL_MIN_PX)
    worker, (calls, threads) = task.result(timeout=30)
    assert worker != here and calls == [(0, PARALLEL_MIN_PX)] and threads == {worker}


def test_a_small_background_task_runs_at_once_and_keeps_its_exception():
    here = threading.current_thread().name
    assert in_background(lambda: threading.current_thread().name, 10).result() == here

    def fails():
        raise RuntimeError("task")
    for pixels in (10, PARALLEL_MIN_PX):
        with pytest.raises(RuntimeError, match="task"):
            in_background(fails, pixels).result(timeout=30)
