"""Keeping the lamp supply's watchdog fed through runs of blocking device exchanges.

The supply switches the lamp off by itself when no command reaches it for `lamp.watchdog_s`, and its
keep-alive (rig.drivers.delta_sm) runs only where the rig clock is given the chance: in a sleep
(rig.core.clock). A wait, a move, a lamp ramp and a simulated exposure sleep; a meter reading, or a
vendor camera's picture, blocks on its device and does not. One such exchange fits the watchdog (the
rig file and the campaign's check bound it, rig.config.watchdog), but a run of them does not: 25 meter
readings of 0.2 s for one E⊥ starved the watchdog, and the lamp went out in the middle of its own
measurement (issue 30). So the engine talks to the meter and the camera through the wrappers below:
after each blocking call, the clock runs whatever keep-alive is due (`clock.sleep(0.0)`), on the
engine's own thread, between two exchanges, as the clock's design wants. The meter is wrapped by
`tended`; the camera by the run's capturer (rig.acquisition.capturer), which knows its kind and the
run's clock: `TendedCamera` for raw frames, `TendedCalibratedCamera` for calibrated pictures. A stop of the axes asked
meanwhile (the clock's sleep check) is honoured there too, like in any other sleep.

A long computation between two exchanges starves it alike on a real rig, where wall time is rig time: the
adaptive sampler's next batch takes seconds (`computed_while_tending`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any, TypeVar

from rig.core.clock import Clock
from rig.core.values import Frame, IlluminanceReading, LuminanceImage, Window
from rig.drivers.interfaces import CalibratedLuminanceCamera, IlluminanceMeter, LuminanceCamera, RigDevices
from rig.planning.points import PlannedPoint, PointSource

T = TypeVar("T")
#: Wall time between two chances the clock gets while a computation runs (a keep-alive is due every W/4 ≥ 5 ms).
COMPUTE_SLICE_S = 0.005


class _Tended:
    """Delegates to the wrapped device (its other methods and attributes too); `_after` gives the clock
    its chance once a blocking call has returned."""

    def __init__(self, device: Any, clock: Clock):
        self._device, self._clock = device, clock

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):            # not set yet (copy, pickle): never look for it in the device
            raise AttributeError(name)
        return getattr(self._device, name)

    def _after(self, result: Any) -> Any:
        self._clock.sleep(0.0)          # due keep-alives run (rig.core.clock); no rig time passes
        return result

    def identity(self) -> str:
        return str(self._device.identity())

    def close(self) -> None:
        self._device.close()


class TendedMeter(_Tended, IlluminanceMeter):
    """A meter whose readings let the clock's keep-alives run between them."""

    def read(self) -> IlluminanceReading:
        return self._after(self._device.read())


class TendedCamera(_Tended, LuminanceCamera):
    """A raw camera whose frames (an HDR series, dark frames, probes) let the keep-alives run between them."""

    def __init__(self, device: LuminanceCamera, clock: Clock):
        super().__init__(device, clock)
        self.sensor = device.sensor

    def capture(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._after(self._device.capture(exposure_s, window))

    def capture_dark(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._after(self._device.capture_dark(exposure_s, window))


class TendedCalibratedCamera(TendedCamera, CalibratedLuminanceCamera):
    """A camera delivering calibrated pictures (the LMK's metering series); an HDR picture is one blocking
    call, which the campaign's check bounds (rig.config.watchdog)."""

    def capture_luminance(self, exposure_s: float, window: Window | None = None) -> LuminanceImage:
        return self._after(self._device.capture_luminance(exposure_s, window))

    def capture_hdr_luminance(self, max_exposure_s: float, min_exposure_s: float, factor: float,
                              window: Window | None = None) -> LuminanceImage:
        return self._after(self._device.capture_hdr_luminance(max_exposure_s, min_exposure_s, factor, window))


def tended(devices: RigDevices) -> RigDevices:
    """`devices` with the meter wrapped (module docstring; the camera is the capturer's to wrap); the devices
    themselves are unchanged (events are routed, and the rig made safe and closed, through either)."""
    return replace(devices, meter=TendedMeter(devices.meter, devices.clock))


def computed_while_tending(clock: Clock, work: Callable[[], T]) -> T:
    """`work()` on a thread of its own while this thread gives the clock its chance every COMPUTE_SLICE_S of wall
    time: the keep-alives due run here, on the thread that owns the devices (`work` must not talk to them). A
    simulated clock does not advance meanwhile (computing takes no rig time). `work`'s exception is raised here;
    an abort raised by the clock's sleep check leaves the computation to end alone (a daemon thread)."""
    outcome: list[Any] = []

    def run() -> None:
        try:
            outcome.append((True, work()))
        except BaseException as exc:  # handed to the caller, whatever it is
            outcome.append((False, exc))
    worker = threading.Thread(target=run, name="rig-computation", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(COMPUTE_SLICE_S)
        clock.sleep(0.0)
    done, value = outcome[0]
    if not done:
        raise value
    return value


def batch_while_tending(source: PointSource, rows: Sequence[Mapping[str, object]], clock: Clock,
                        event: Callable[..., None]) -> list[PlannedPoint]:
    """`source`'s next batch after `rows`, computed while the clock's keep-alives run (`computed_while_tending`);
    the events it reports are written afterwards through `event`, on this thread: a keep-alive may write one
    meanwhile, and the dataset has one writer."""
    said: list[tuple[str, dict[str, Any]]] = []
    batch = computed_while_tending(clock, lambda: list(source.next_batch(
        rows, lambda kind, **fields: said.append((kind, fields)))))
    for kind, fields in said:
        event(kind, **fields)
    return batch
