"""Neutral-density attenuation for points too bright for the camera's shortest exposure.

A point is taken through the clearest filter of the wheel that does not clip its
ROI: the HDR merge can lengthen exposures for a dark ROI, but cannot shorten them
below the sensor's minimum, so a glossy peak or a retroreflective sheet seen at
retroreflection would otherwise come back as a lower bound (`roi_saturated`).

Per point, on the filter the previous point left in the beam:
1. While a clearer filter exists, one probe frame of the ROI (the capturer's `probe`) at the exposure that
   gives, through the present filter, the signal the clearer one would give at the
   sensor's shortest exposure: if its brightest pixel stays below `CLEARER_HEADROOM`
   of the usable range, the clearer filter will not clip either: move to it and
   probe again. This keeps a dense filter from costing long exposures on the dim
   points after a bright stretch.
2. The ordinary capture (the run's capturer, rig.acquisition.capturer). If ROI
   pixels clipped in every exposure (the acquisition says so), move to the next
   denser filter and take the point again. A camera that calibrates its own pictures
   never clips (it has its own attenuation): the wheel stays on the clearest filter.
The wheel wraps the run's capturer once (`AttenuatingCapturer`, chosen by rig.acquisition.capturer
`capturer_for`): it takes points with the capturer's interface, so the engine does not know it is there, and
a rig without a wheel never reaches this module. Points that never saturate pay nothing: no probe is taken
while the clearest filter is in the beam, so the wheel never moves for them.

The wheel turns one position per move, the shorter way round: a move blocks the
link for about a second per position, and the lamp supply's watchdog is fed only
between blocking calls (rig.core.clock keep-alives), so a long move is a series of
short ones with the keep-alives run in between.

Darks do not depend on the filter (no light reaches the sensor), so the dark-frame
cache stays per exposure. The transmission's calibration uncertainty becomes the
point's `u_rel_attenuation`; the filter is recorded per point (brdf.csv
`filter_position`, `filter_transmission`) and each move is an event.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields, replace

from rig.acquisition.capturing import Capturer, PointAcquisition
from rig.config.rigfile import AttenuatorConfig
from rig.core import events
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import PointCapture, SensorInfo, Window
from rig.drivers.interfaces import Attenuator, RigDevices

#: A clearer filter is chosen when its predicted ROI peak at the shortest exposure stays below this fraction
#: of the usable raw range: texture and glints vary from frame to frame and view to view.
CLEARER_HEADROOM = 0.5


@dataclass(frozen=True)
class Filter:
    """A wheel position and its calibrated transmission (value, relative standard uncertainty)."""

    position: int
    transmission: float
    u_rel: float


def attenuated(capture: PointCapture, used: Filter) -> PointCapture:
    """The capture as if no filter were in the beam: every luminance (each `…_cd_m2` field, the image too)
    divided by the transmission, whose relative uncertainty joins u_luminance (and is recorded apart)."""
    t = used.transmission
    luminances = {f.name: getattr(capture, f.name) for f in fields(capture)
                  if f.name.endswith("_cd_m2") and getattr(capture, f.name) is not None}
    scaled = luminances if t == 1.0 else {name: value / t for name, value in luminances.items()}  # 1: open
    lum = scaled["luminance_cd_m2"]
    scaled["u_luminance_cd_m2"] = math.hypot(scaled["u_luminance_cd_m2"], used.u_rel * lum)
    return replace(capture, **scaled, filter_position=used.position, transmission=t, u_rel_attenuation=used.u_rel)


class Attenuation:
    """The filter wheel with its calibrated filters, clearest first; takes each point through the filter
    it needs (module docstring). `event(kind, **fields)` records each move."""

    def __init__(self, wheel: Attenuator, filters: Sequence[Filter], event: Callable[..., None], clock: Clock):
        self.wheel = wheel
        self.clock = clock
        self.filters = sorted(filters, key=lambda f: -f.transmission)
        self.event = event
        beyond = [f.position for f in self.filters if f.position > wheel.positions]
        if beyond:
            raise DeviceError("attenuator", f"{wheel.identity()} has {wheel.positions} positions; the rig file's "
                                            f"filters name position(s) {beyond}")
        self.index = 0
        self._started = False          # the wheel is put on the clearest filter before the first point
        self._at: int | None = None    # the wheel's position as rig left it (None: unknown, ask the wheel)

    @property
    def current(self) -> Filter:
        return self.filters[self.index]

    def acquire(self, capturer: Capturer) -> tuple[PointAcquisition, Filter]:
        """The point's acquisition (`capturer.acquire()`) through the clearest filter that does not clip its ROI,
        and that filter."""
        if not self._started:
            self._move(0, reason="start")
            self._started = True
        while self.index > 0 and self._clearer_fits(capturer):
            self._move(self.index - 1, reason="clearer filter suffices")
        while True:
            acquisition = capturer.acquire()
            if not (self.index + 1 < len(self.filters) and acquisition.clipped):
                return acquisition, self.current
            self._move(self.index + 1, reason="ROI saturated at the shortest exposure")

    def _clearer_fits(self, capturer: Capturer) -> bool:
        sensor = capturer.sensor
        clearer = self.filters[self.index - 1]
        probe_s = min(sensor.min_exposure_s * clearer.transmission / self.current.transmission, sensor.max_exposure_s)
        peak, realised_s = capturer.probe(probe_s)
        # the probe's peak scaled to what the clearer filter gives at the shortest exposure
        scale = (sensor.min_exposure_s * clearer.transmission) / (realised_s * self.current.transmission)
        return peak * scale < CLEARER_HEADROOM

    def _move(self, index: int, reason: str) -> None:
        target = self.filters[index]
        start, self._at = (self.wheel.position() if self._at is None else self._at), None
        for position in shorter_way(start, target.position, self.wheel.positions):
            self.wheel.move_to(position)
            self._at = position
            self.clock.sleep(0.0)          # between single-position moves: due keep-alives (the lamp's) run
        self.index = index
        self.event(events.FILTER, device="attenuator", what=reason, position=target.position,
                   transmission=target.transmission)


def shorter_way(start: int, target: int, positions: int) -> list[int]:
    """The positions a wheel of `positions` passes on its way from `start` to `target` (1-based), one at a
    time, the shorter way round (forward on a tie), `target` last; empty if it is there."""
    forward = (target - start) % positions
    step, count = (1, forward) if forward <= positions - forward else (-1, positions - forward)
    return [(start - 1 + step * k) % positions + 1 for k in range(1, count + 1)]


def attenuation_for(devices: RigDevices, filters: AttenuatorConfig | None,
                    event: Callable[..., None]) -> Attenuation | None:
    """The run's attenuation: None on a rig without a filter wheel."""
    if devices.attenuator is None or filters is None:
        return None
    return Attenuation(devices.attenuator, [Filter(f.position, f.transmission, f.u_rel) for f in filters.filters],
                       event, devices.clock)


@dataclass(frozen=True)
class AttenuatedAcquisition:
    """A point's acquisition through the filter `used`: it reduces to the capture as if no filter were in the
    beam (`attenuated`)."""

    acquisition: PointAcquisition
    used: Filter

    @property
    def clipped(self) -> bool:
        return self.acquisition.clipped

    def reduce(self) -> PointCapture:
        return attenuated(self.acquisition.reduce(), self.used)


class AttenuatingCapturer:
    """The run's capturer behind the filter wheel: each point through the filter it needs (module docstring)."""

    def __init__(self, capturer: Capturer, attenuation: Attenuation):
        self.capturer, self.attenuation = capturer, attenuation

    @property
    def sensor(self) -> SensorInfo:
        return self.capturer.sensor

    @property
    def roi(self) -> Window:
        return self.capturer.roi

    def acquire(self) -> AttenuatedAcquisition:
        return AttenuatedAcquisition(*self.attenuation.acquire(self.capturer))

    def probe(self, exposure_s: float) -> tuple[float, float]:
        """The wrapped capturer's probe, through the filter in the beam."""
        return self.capturer.probe(exposure_s)
