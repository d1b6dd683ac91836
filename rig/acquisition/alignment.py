"""Aligning the arm on the sample's specular peak before a campaign (campaign key `alignment`).

On a steep lobe the largest error of a point is not the capture but where the camera looks
relative to the lobe's axis: the arm's zero error, and the sample's mounting tilt, which turns the
mirror direction by twice its angle. Labs therefore align a glossy sample on its own specular
reflection. Here the arm scans a small grid around the nominal mirror direction at one incidence,
rig.physics.peak_fit locates the peak in arm coordinates, and from then on the engine commands
every arm move offset by it (rig.acquisition.moves.Mover.arm_zero_deg), so the recorded angles are
relative to the sample as mounted. The stage's axis in the plane of incidence is parallel to the
arm's azimuth axis, so one incidence fixes the offset for all.

A scan is tens of moves and captures, minutes on a real rig: the engine is called before each step
(`before_step`), to report progress and to honour a stop request there (rig.acquisition.stopping), so
that a Ctrl+C ends the scan within one step, not after it (issue 30).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from rig.acquisition.moves import Mover
from rig.config.campaign import SpecularAlignment
from rig.core import events
from rig.core.values import PointCapture
from rig.physics import geometry as geo
from rig.physics.peak_fit import LogPeak, PeakNotFound, fit_log_peak


class AlignmentError(RuntimeError):
    """The specular peak could not be found, or lies too far from where the rig expects it."""


@dataclass(frozen=True)
class ArmAlignment:
    """The encoder readings (relative to nominal) at which the arm looks along the sample's mirror direction."""

    arm_azimuth_zero_deg: float
    arm_polar_zero_deg: float
    u_deg: float                  # standard uncertainty of either offset (the larger)
    theta_i_deg: float
    lobe_width_deg: float         # σ of the peak along its narrower axis, as the scan saw it

    def as_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ArmAlignment:
        return cls(**{k: float(d[k]) for k in cls.__dataclass_fields__})


def scan_grid_deg(spec: SpecularAlignment) -> tuple[np.ndarray, np.ndarray]:
    """Arm (azimuth, polar) offsets of the scan: the nominal mirror direction, a serpentine over the grid
    (each move one step), and the nominal direction again, so that the fit can tell a drift of the lamp
    during the scan from the lobe's slope (rig.physics.peak_fit)."""
    half = (spec.steps - 1) // 2
    ticks = spec.step_deg * np.arange(-half, half + 1)
    rows = [(ticks if k % 2 == 0 else ticks[::-1], np.full(spec.steps, p)) for k, p in enumerate(ticks)]
    az = np.concatenate([[0.0], *(r[0] for r in rows), [0.0]])
    polar = np.concatenate([[0.0], *(r[1] for r in rows), [0.0]])
    return az, polar


def _unobserved(step: int, steps: int) -> None:
    """`before_step` of a scan nobody watches or stops (a test's)."""


def _scan(where: str, spec: SpecularAlignment, mover: Mover, capture: Callable[[], PointCapture],
          event: Callable[..., None], nominal: np.ndarray, centre: tuple[float, float],
          before_step: Callable[[int, int], None]) -> LogPeak:
    """One scan around `centre` (arm offsets from `nominal`, degrees); its peak in offsets from `nominal`.
    `before_step(k, n)` before step k of n (from 0) may raise to end the scan there."""
    stage_v, stage_n, arm_a, arm_p = (float(v) for v in nominal)
    d_az, d_polar = scan_grid_deg(spec)
    luminance, at_az, at_polar, at_s = (np.empty(d_az.size) for _ in range(4))
    for k, (da, dp) in enumerate(zip(d_az + centre[0], d_polar + centre[1])):
        before_step(k, d_az.size)
        mover.move((stage_v, stage_n, arm_a + float(da), arm_p + float(dp)))
        _, _, read_az, read_polar = mover.read_back()         # where the encoders say the arm came to rest
        at_az[k], at_polar[k], at_s[k] = read_az - arm_a, read_polar - arm_p, mover.dev.clock.now()
        cap = capture()
        if "roi_saturated" in cap.flags or not cap.luminance_cd_m2 > 0:
            raise AlignmentError(f"{where}: the ROI {'saturates' if cap.luminance_cd_m2 > 0 else 'is dark'} at "
                                 f"arm offset ({da:+.3f}°, {dp:+.3f}°); a filter wheel or another incidence is needed")
        luminance[k] = cap.luminance_cd_m2
    event(events.ALIGNMENT_SCAN, arm_azimuth_deg=arm_a, arm_polar_deg=arm_p, d_azimuth_deg=at_az.tolist(),
          d_polar_deg=at_polar.tolist(), luminance_cd_m2=luminance.tolist(), rig_clock_s=at_s.tolist())
    try:
        return fit_log_peak(at_az, at_polar, luminance, at_s)
    except PeakNotFound as exc:
        raise AlignmentError(f"{where}: {exc}; is the sample glossy, and its peak within "
                             f"±{spec.step_deg * (spec.steps - 1) / 2:g}° of the mirror direction?") from None


def align_on_specular(spec: SpecularAlignment, mover: Mover, capture: Callable[[], PointCapture],
                      event: Callable[..., None], before_step: Callable[[int, int], None] = _unobserved
                      ) -> ArmAlignment:
    """Scan, fit, check, and return the arm's offsets; the mover is left uncorrected (the caller applies them).
    `before_step(k, n)` is called before step k of n of each scan (module docstring).

    A peak found more than half a step from the scan's centre is scanned once more, centred on it: the
    log of a real lobe is a quadratic only near its top, so a grid centred on the peak fits it best.
    """
    where = f"alignment on the specular peak at θi={spec.theta_i_deg:g}°"
    nominal = geo.inverse_deg(spec.theta_i_deg, 0.0, spec.theta_i_deg, 180.0, mover.rig.axes.limits(),
                              mover.position).as_array()
    if not np.all(np.isfinite(nominal)):
        raise AlignmentError(f"{where}: the mirror geometry is outside the axes' limits")
    peak = _scan(where, spec, mover, capture, event, nominal, (0.0, 0.0), before_step)
    if max(abs(peak.x0), abs(peak.y0)) > spec.step_deg / 2 and math.hypot(peak.x0, peak.y0) <= spec.max_offset_deg:
        peak = _scan(where, spec, mover, capture, event, nominal, (peak.x0, peak.y0), before_step)
    offset = math.hypot(peak.x0, peak.y0)
    if offset > spec.max_offset_deg:
        raise AlignmentError(f"{where}: the peak lies {offset:.3f}° from the nominal mirror direction, beyond "
                             f"alignment.max_offset_deg {spec.max_offset_deg:g}°: check how the sample is mounted")
    return ArmAlignment(arm_azimuth_zero_deg=peak.x0, arm_polar_zero_deg=peak.y0, u_deg=max(peak.u_x0, peak.u_y0),
                        theta_i_deg=spec.theta_i_deg, lobe_width_deg=peak.width)


def align_run(spec: SpecularAlignment, manifest: dict[str, Any], mover: Mover, capture: Callable[[], PointCapture],
              event: Callable[..., None], update_manifest: Callable[..., None],
              before_step: Callable[[int, int], None] = _unobserved) -> ArmAlignment:
    """Align the arm for a run and apply it to `mover`: by a scan (`before_step(k, n)` before each step),
    or as the run being resumed was aligned (its manifest's `alignment`), so that every row of a dataset is
    relative to the same zero."""
    saved = manifest.get("alignment")
    if saved is None:
        found = align_on_specular(spec, mover, capture, event, before_step)
        update_manifest(alignment=found.as_dict())
    else:
        found = ArmAlignment.from_dict(saved)
    event(events.ALIGNED, reused=saved is not None, **found.as_dict())
    mover.align((found.arm_azimuth_zero_deg, found.arm_polar_zero_deg))
    return found
