"""E⊥ from meter readings, its drift correction between readings, and the BRDF it turns a luminance into (pure).

The lamp drifts (warm-up tail, ageing), so E⊥ is re-measured on a schedule and
each point gets E⊥ interpolated linearly in rig time between the readings that
bracket it. What linear interpolation cannot know, the curvature of the drift
between two readings, is taken as a rectangular distribution over the change
between them: u_drift = |E₂ − E₁| / √12 (conservative: measurement noise in the
readings inflates the change too).

The BRDF (`brdf_from_luminance`, vectorised): f_r = L / (E⊥ cos θi) with
E(θi) = E⊥ cos θi on the sample plane; the relative standard uncertainty
combines, uncorrelated, u_rel(f)² = u_rel(L)² + u_rel(E⊥)² + (tan θi · u_θ)²,
u_θ in radians. Towards grazing incidence cos θi → 0 and both f_r and its angle
term blow up, so these are flagged and kept finite instead of producing inf/NaN
that would break CSV readers and fits.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from rig.core.values import IlluminanceReading

#: Degrees of freedom given to the meter's specified repeatability when pooling it
#: with the spread of a few readings (a 5-reading std alone is too uncertain for k = 2).
PRIOR_DOF = 10


def underload_u(floor: float) -> float:
    """Standard uncertainty of a reading known only to lie below `floor` (a meter's underload).

    Light makes a photocurrent of one sign, so the quantity lies in [0, floor): with nothing known
    inside that interval, a rectangular distribution over it, whose midpoint floor/2 is the value
    the reading carries (rig.core.values.IlluminanceReading.floor_a) and whose standard uncertainty
    is floor/√12 (GUM 4.3.7). For the P-9710 the floor is the last digit the range displays (its
    resolution, full scale / 2000: 0.1 pA on range 7); the meter's offset error (±2 pA on ranges 6
    and 7, manual §12.2) belongs to the range, not to the underload.
    """
    return floor / math.sqrt(12.0)


@dataclass(frozen=True)
class IlluminanceEstimate:
    """E⊥ averaged over `n` readings at `rig_time_s`, with statistical and calibration parts."""

    value_lx: float
    u_stat_lx: float
    u_cal_lx: float
    n: int
    rig_time_s: float

    @property
    def u_lx(self) -> float:
        return math.hypot(self.u_stat_lx, self.u_cal_lx)


def estimate(readings_lx: np.ndarray, rig_time_s: float, repeatability_rel: float,
             calibration_u_rel: float, range_u_rel: np.ndarray | float = 0.0) -> IlluminanceEstimate:
    """Mean of readings; the std of one reading pools the observed spread with the meter's spec.

    `range_u_rel` is each reading's relative uncertainty from the meter's range it was taken on
    (gain and offset of that range, from the certificate). It is the same error for every reading
    on the range, so it does not average down like the scatter: taken as fully correlated between
    the readings (conservative when they straddle ranges), it adds |Σ uᵢ·Eᵢ| / n in quadrature to
    the statistical part. The calibration part stays separate: it is one certificate for all readings.
    """
    values = np.asarray(readings_lx, float)
    n = values.size
    mean = float(values.mean())
    spec_var = (repeatability_rel * mean) ** 2
    observed_var = float(values.var(ddof=1)) if n >= 2 else 0.0
    pooled_var = ((n - 1) * observed_var + PRIOR_DOF * spec_var) / (n - 1 + PRIOR_DOF)
    u_range = abs(float(np.sum(np.broadcast_to(np.asarray(range_u_rel, float), values.shape) * values))) / n
    return IlluminanceEstimate(mean, math.sqrt(pooled_var / n + u_range ** 2), calibration_u_rel * mean, n,
                               rig_time_s)


class NoLightError(ValueError):
    """Meter readings of which no E⊥ can be made: the detector saw no light (the message gives the figures; the
    caller names the meter)."""


def estimate_of_readings(readings: Sequence[IlluminanceReading], rig_time_s: float, repeatability_rel: float,
                         calibration_u_rel: float, range_u_rel: Sequence[float]) -> IlluminanceEstimate:
    """E⊥ of a batch of meter readings at `rig_time_s` (`estimate`: the meter's repeatability and calibration, and
    each reading's range, `range_u_rel[range_index]`); NoLightError when the batch is no E⊥.

    A batch with a reading in the dark is no E⊥: a non-positive mean, or any underload (the meter saw less than
    its range resolves, `IlluminanceReading.floor_a`). Dividing luminances by such an E⊥ would give BRDF values
    of pure noise, so the batch is refused, with the figures: the run engine raises it as the meter's
    DeviceError, then looks for a lamp that went out (and pauses for it) or ends the run with that message. A lab
    expects the same: light on the detector, or no measurement.
    """
    dark = [(r, r.floor_a) for r in readings if r.floor_a is not None]
    if dark:
        r, floor = dark[0]
        u_lx = underload_u(floor) * r.calibration_lx_per_a
        raise NoLightError(f"{len(dark)} of {len(readings)} readings below the meter's floor (underload: "
                           f"less than {floor:g} A on range {r.range_index}, E⊥ taken as "
                           f"{r.illuminance_lx:.2g} ± {u_lx:.2g} lx): no light on the detector")
    values = np.array([r.illuminance_lx for r in readings])
    if not values.mean() > 0:
        raise NoLightError(f"E⊥ reads {values.mean():g} lx (photocurrent {readings[0].photocurrent_a:g} A):"
                           " no light on the detector")
    range_u = [0.0 if r.range_index is None else range_u_rel[r.range_index] for r in readings]
    return estimate(values, rig_time_s, repeatability_rel, calibration_u_rel, np.array(range_u))


@dataclass(frozen=True)
class InterpolatedIlluminance:
    value_lx: np.ndarray
    u_lx: np.ndarray          # statistical (weighted) ⊕ calibration ⊕ drift
    u_drift_lx: np.ndarray


def interpolate(before: IlluminanceEstimate, after: IlluminanceEstimate,
                rig_time_s: np.ndarray) -> InterpolatedIlluminance:
    """E⊥ at `rig_time_s`, linear between two readings (clamped to their interval)."""
    t = np.asarray(rig_time_s, float)
    span = after.rig_time_s - before.rig_time_s
    w_after = np.clip((t - before.rig_time_s) / span, 0.0, 1.0) if span > 0 else np.ones_like(t)
    w_before = 1.0 - w_after
    value = w_before * before.value_lx + w_after * after.value_lx
    u_stat = np.hypot(w_before * before.u_stat_lx, w_after * after.u_stat_lx)
    u_cal = w_before * before.u_cal_lx + w_after * after.u_cal_lx      # one certificate: fully correlated
    u_drift = np.full_like(t, abs(after.value_lx - before.value_lx) / math.sqrt(12.0))
    return InterpolatedIlluminance(value, np.sqrt(u_stat ** 2 + u_cal ** 2 + u_drift ** 2), u_drift)


@dataclass(frozen=True)
class ReadingSchedule:
    """When to re-measure E⊥: at each series start, every N points, or every T seconds of rig time."""

    policy: str            # per_series | every_n_points | every_minutes
    every: float = 0.0

    def due(self, new_series: bool, points_since: int, seconds_since: float) -> bool:
        if self.policy == "per_series":
            return new_series
        if self.policy == "every_n_points":
            return points_since >= self.every
        return seconds_since >= 60.0 * self.every


#: Smallest cos θi used; at and beyond it (θi ≈ 90°) the values are finite but meaningless.
COS_MIN = 1e-6
#: θi from which a point is flagged grazing_incidence: the campaign's default `limits.grazing_limit_deg`.
GRAZING_LIMIT_DEG = 88.0


@dataclass(frozen=True)
class BrdfResult:
    """Arrays broadcast from the inputs of `brdf_from_luminance`."""

    brdf_per_sr: np.ndarray
    u_brdf_per_sr: np.ndarray        # combined standard uncertainty (k = 1)
    illuminance_lx: np.ndarray       # E(θi) = E⊥ cos θi used
    grazing_incidence: np.ndarray    # bool: θi ≥ grazing limit, or cos θi ≤ COS_MIN


def brdf_from_luminance(luminance_cd_m2: ArrayLike, u_luminance_cd_m2: ArrayLike,
                        illuminance_normal_lx: ArrayLike, u_illuminance_normal_lx: ArrayLike,
                        theta_i_deg: ArrayLike, u_theta_deg: ArrayLike,
                        grazing_limit_deg: float = GRAZING_LIMIT_DEG) -> BrdfResult:
    """BRDF (sr⁻¹) and its standard uncertainty from ROI luminance and E⊥.

    All arguments broadcast against each other. The uncertainty is computed in
    absolute form, u(f)² = (u_L/E)² + (f u_E⊥/E⊥)² + (f tan θi u_θ)², which equals
    the relative form but stays defined for L = 0 (an unlit ROI); `hypot` keeps
    the squares from overflowing at grazing incidence. E⊥ must be
    positive: a zero reading is a meter fault, not a measurement.
    """
    lum, u_lum, e_normal, u_e_normal, theta_deg, u_theta = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (luminance_cd_m2, u_luminance_cd_m2,
                                               illuminance_normal_lx, u_illuminance_normal_lx,
                                               theta_i_deg, u_theta_deg)))
    if np.any(~(e_normal > 0)):
        raise ValueError("illuminance_normal_lx must be positive")
    theta = np.deg2rad(theta_deg)
    cos_raw = np.cos(theta)
    grazing = (cos_raw <= COS_MIN) | (np.abs(theta_deg) >= grazing_limit_deg)
    cos_i = np.maximum(cos_raw, COS_MIN)
    tan_i = np.abs(np.sin(theta)) / cos_i
    illuminance = e_normal * cos_i
    brdf = lum / illuminance
    u_brdf = np.hypot(np.hypot(u_lum / illuminance, brdf * u_e_normal / e_normal),
                      brdf * tan_i * np.deg2rad(u_theta))
    return BrdfResult(brdf_per_sr=brdf, u_brdf_per_sr=u_brdf, illuminance_lx=illuminance,
                      grazing_incidence=grazing)
