"""rig.core.bands: row bands on worker threads, and tasks in the background."""

import threading

import pytest

from rig.core import bands
from rig.core.bands import PARALLEL_MIN_PX, run_in_bands


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


def test_a_shared_job_runs_every_part_once_and_the_parts_bands_in_their_thread():
    """A worker waiting on bands queued behind it on its own pool could wait forever: inside a part on a
    worker, run_in_bands keeps to the part's thread. The caller takes parts too once its own task is done."""
    done, threads, here = [], set(), threading.current_thread().name

    def part(k):
        calls, band_threads = covered(PARALLEL_MIN_PX, 2)
        if threading.current_thread().name != here:
            assert calls == [(0, PARALLEL_MIN_PX)] and band_threads == {threading.current_thread().name}
        done.append(k)
        threads.add(threading.current_thread().name)
        if threading.current_thread().name != here:
            on_worker.set()
    on_worker = threading.Event()

    def task():                                   # until the worker has a part (with more than one CPU)
        assert bands.workers() == 1 or on_worker.wait(timeout=60)
        return "task"
    assert bands.shared([lambda k=k: part(k) for k in range(6)], task, PARALLEL_MIN_PX) == "task"
    assert sorted(done) == list(range(6)) and (bands.workers() == 1 or threads - {here})


def test_a_small_shared_job_runs_in_the_callers_thread_and_raises_what_a_part_raises():
    here = threading.current_thread().name
    seen = []
    bands.shared([lambda: seen.append(threading.current_thread().name)] * 2, lambda: None, 10)
    assert seen == [here, here]

    def fails():
        raise RuntimeError("part")
    for pixels in (10, PARALLEL_MIN_PX):
        with pytest.raises(RuntimeError, match="part"):
            bands.shared([fails, fails], lambda: None, pixels)
