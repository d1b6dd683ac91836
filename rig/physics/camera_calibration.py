"""Radiometric calibration of a raw camera after EMVA 1288 (Release 4.0 Linear): pure numpy, no I/O.

A raw machine-vision camera reports counts; `rig calibrate camera` turns frames of a covered lens and of a
uniform source of known luminance into what `rig.acquisition.capture` needs to report cd/m²:

- dark mean and DSNU per exposure time (EMVA 1288 4.0, "Dark signal nonuniformity"): the spatial variance
  of the averaged dark stack, less the temporal variance left in that average;
- the photon-transfer gain K and the temporal dark noise σd ("Sensitivity, linearity and noise": the slope
  of σ²_y − σ²_y.dark against μ_y − μ_y.dark up to 70 % of saturation, fitted through zero);
- linearity over exposure time at a fixed luminance ("Linearity": a straight-line fit weighted by 1/μ
  between 5 % and 95 % of saturation, relative deviations δ and LE = (max δ − min δ)/2 in %);
- the flat field: each pixel's response relative to the centre, split into a smooth lens fall-off (a 2-D
  polynomial) and PRNU, the spatial std of what the polynomial leaves, less the temporal noise
  ("Photo response nonuniformity"; EMVA removes the smooth part with a high-pass filter instead);
- the luminance coefficient k (cd/m² per DN/s) at the centre from a reference luminance, with its budget.

Temporal variances come from the per-pixel sample variance of a stack of frames, which for two frames is
EMVA's difference formula σ²_y = ½·mean((y_A − y_B)²) − ½(μ_A − μ_B)² up to the mean-difference term.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rig.core.values import SensorInfo, Window
from rig.physics.hdr import QUANTISATION_VAR_DN2

#: Linearity is fitted between these fractions of the saturation signal (above dark): EMVA 1288.
LINEAR_RANGE = (0.05, 0.95)
#: The photon-transfer gain is fitted up to this fraction of the saturation signal: EMVA 1288.
PTC_MAX_FRACTION = 0.70
#: Pixels used at most for the fall-off fit (a regular subsample beyond), to bound its memory.
FIT_MAX_PIXELS = 200_000


@dataclass(frozen=True)
class StackStats:
    """Mean image of a stack of frames of one exposure and its temporal noise."""

    mean_dn: np.ndarray          # (H, W) average of the frames
    var_dn2: np.ndarray          # (H, W) temporal variance of one frame, per pixel (or a scalar for all)
    frames: int

    @property
    def temporal_var_dn2(self) -> float:
        """Temporal variance of one frame, averaged over the pixels (EMVA σ²_y)."""
        return float(np.mean(self.var_dn2))

    @property
    def var_of_mean_dn2(self) -> float:
        """Temporal variance left in one pixel of the average, averaged over the pixels."""
        return self.temporal_var_dn2 / self.frames


def stack_stats(stack: np.ndarray) -> StackStats:
    """Mean and temporal variance of a stack (n ≥ 2, H, W) of frames taken under the same conditions."""
    stack = np.asarray(stack, dtype=float)
    if stack.ndim != 3 or stack.shape[0] < 2:
        raise ValueError(f"need a stack of at least two frames (n, H, W), got shape {stack.shape}")
    return StackStats(stack.mean(axis=0), stack.var(axis=0, ddof=1), stack.shape[0])


def spatial_variance(stats: StackStats) -> float:
    """Spatial variance of the mean image less the temporal variance left in it (EMVA s²_y = s²_measured −
    σ²_y/L); may come out slightly negative when there is no nonuniformity."""
    return float(stats.mean_dn.var(ddof=1)) - stats.var_of_mean_dn2


@dataclass(frozen=True)
class DarkLevel:
    """Dark signal of one exposure time (EMVA 1288 dark signal and DSNU), in DN."""

    exposure_s: float
    mean_dn: float
    dsnu_dn: float               # spatial std of the dark signal, temporal noise removed
    temporal_std_dn: float       # σ_y.dark of one frame
    frames: int


def dark_level(stats: StackStats, exposure_s: float) -> DarkLevel:
    """Dark mean, DSNU and temporal noise of the stats of a stack of dark frames of one exposure."""
    return DarkLevel(exposure_s, float(stats.mean_dn.mean()), float(np.sqrt(max(spatial_variance(stats), 0.0))),
                     float(np.sqrt(stats.temporal_var_dn2)), stats.frames)


@dataclass(frozen=True)
class PhotonTransfer:
    """System gain K (DN/e⁻) and temporal dark noise σd (e⁻) with standard uncertainties."""

    gain_dn_per_e: float
    u_gain_dn_per_e: float
    read_noise_e: float
    u_read_noise_e: float


def photon_transfer(signal_dn: np.ndarray, var_dn2: np.ndarray, dark_var_dn2: float,
                    saturation_dn: float) -> PhotonTransfer:
    """K as the slope through zero of var_dn2 (σ²_y − σ²_y.dark) against signal_dn (μ_y − μ_y.dark) up to 70 %
    of `saturation_dn` (the largest signal above dark), and σd = √(σ²_y.dark − 1/12)/K (EMVA 1288 photon
    transfer). The uncertainty of K is the slope's from the fit residuals, of σd from K's alone."""
    x, y = np.asarray(signal_dn, float), np.asarray(var_dn2, float)
    use = (x > 0) & (x <= PTC_MAX_FRACTION * saturation_dn)
    if use.sum() < 2:
        raise ValueError("photon transfer needs at least two exposures below 70 % of saturation")
    x, y = x[use], y[use]
    k = float(np.dot(x, y) / np.dot(x, x))
    dof = x.size - 1
    u_k = float(np.sqrt(np.sum((y - k * x) ** 2) / dof / np.dot(x, x))) if dof else 0.0
    sigma_d = float(np.sqrt(max(dark_var_dn2 - QUANTISATION_VAR_DN2, 0.0))) / k
    return PhotonTransfer(k, u_k, sigma_d, sigma_d * u_k / k)


@dataclass(frozen=True)
class Linearity:
    """Straight-line fit of signal against exposure time at a fixed luminance (EMVA 1288 linearity)."""

    slope_dn_s: float
    offset_dn: float
    deviation_rel: np.ndarray    # δ per exposure (not in %), NaN outside the fitted range
    le_percent: float            # (max δ − min δ)/2 in %
    u_le_percent: float          # from the temporal noise of the means
    used: np.ndarray             # exposures inside LINEAR_RANGE


def linearity(exposure_s: np.ndarray, signal_dn: np.ndarray, u_signal_dn: np.ndarray,
              saturation_dn: float) -> Linearity:
    """Fit signal_dn (above dark) = offset + slope·t between 5 % and 95 % of `saturation_dn`, weighted by
    1/signal so that relative deviations count alike, as EMVA 1288 does.

    LE, a half range, is biased upwards by noise: a perfectly linear camera shows the expected half range of
    its n deviations' noise. u(LE) is that, E[½ range of n normals] × rms u(δ), so a camera whose LE is
    within about 2 u(LE) is linear as far as this sweep can tell, and LE − LE_true stays within it."""
    t, y, u = (np.asarray(a, float) for a in (exposure_s, signal_dn, u_signal_dn))
    used = (y >= LINEAR_RANGE[0] * saturation_dn) & (y <= LINEAR_RANGE[1] * saturation_dn)
    if used.sum() < 3:
        raise ValueError(f"linearity needs at least three exposures between {LINEAR_RANGE[0]:.0%} and "
                         f"{LINEAR_RANGE[1]:.0%} of saturation, got {int(used.sum())}")
    offset, slope = np.polynomial.polynomial.polyfit(t[used], y[used], 1, w=1.0 / y[used])
    fit = offset + slope * t
    deviation = np.where(used, (y - fit) / fit, np.nan)
    le = 50.0 * float(np.nanmax(deviation) - np.nanmin(deviation))
    u_le = 100.0 * expected_half_range(int(used.sum())) * float(np.sqrt(np.mean((u[used] / fit[used]) ** 2)))
    return Linearity(float(slope), float(offset), deviation, le, u_le, used)


def expected_half_range(n: int) -> float:
    """E[(max − min)/2] of n independent standard normal values: ½∫(1 − Φⁿ − (1 − Φ)ⁿ) dx (Tippett 1925)."""
    x = np.linspace(-10.0, 10.0, 8001)
    cdf = 0.5 * (1.0 + np.vectorize(math.erf)(x / math.sqrt(2.0)))
    return 0.5 * float(np.sum(1.0 - cdf ** n - (1.0 - cdf) ** n) * (x[1] - x[0]))


def _design(x: np.ndarray, y: np.ndarray, degree: int) -> np.ndarray:
    """Columns x^i·y^j, i + j ≤ degree, of a full 2-D polynomial."""
    return np.stack([x ** i * y ** (d - i) for d in range(degree + 1) for i in range(d + 1)], axis=-1)


def _coordinates(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Pixel-centre coordinates scaled to −1…1 across the sensor (conditioning of the fit)."""
    y, x = np.mgrid[0:height, 0:width].astype(float)
    return (x + 0.5) / width * 2 - 1, (y + 0.5) / height * 2 - 1


def falloff_map(coefficients: np.ndarray, height: int, width: int, degree: int) -> np.ndarray:
    """The smooth relative response (H, W) of a fitted fall-off polynomial."""
    return _design(*_coordinates(height, width), degree) @ np.asarray(coefficients, float)


@dataclass(frozen=True)
class FlatField:
    """Per-pixel response relative to the centre window, and its split into fall-off and PRNU."""

    relative: np.ndarray         # (H, W), mean 1 over `centre`: what the merged rate is divided by
    u_pixel_rel: float           # temporal noise of one pixel of `relative`
    degree: int
    coefficients: np.ndarray     # of the fall-off polynomial in coordinates −1…1
    corner_rel: float            # fall-off at the four corners (mean), relative to the centre
    u_corner_rel: float
    prnu_rel: float              # spatial std of relative / fall-off − 1, temporal noise removed
    u_prnu_rel: float


def flat_field(flat: StackStats, dark: StackStats, centre: Window, degree: int = 4) -> FlatField:
    """Flat field of a uniformly lit sensor from the stats of a flat stack and a dark stack of one exposure.

    The fall-off polynomial is least squares on (a subsample of) all pixels; its corner value's uncertainty
    comes from the fit's covariance with the residual (PRNU + noise) as independent per-pixel scatter.
    u(PRNU) combines the sampling of a std over N pixels, s/√(2(N−1)), with that of the temporal term."""
    signal = flat.mean_dn - dark.mean_dn
    h, w = signal.shape
    rows, cols = Window(0, 0, w, h).inner(centre)
    level = float(signal[rows, cols].mean())
    if not level > 0:
        raise ValueError("the flat frames are no brighter than the dark frames at the centre")
    relative = signal / level
    var_relative = (flat.var_dn2 / flat.frames + dark.var_dn2 / dark.frames) / level ** 2     # per pixel
    x, y = _coordinates(h, w)
    step = max(1, int(np.ceil(np.sqrt(h * w / FIT_MAX_PIXELS))))
    a = _design(x[::step, ::step].ravel(), y[::step, ::step].ravel(), degree)
    b = relative[::step, ::step].ravel()
    coefficients, *_ = np.linalg.lstsq(a, b, rcond=None)
    smooth = falloff_map(coefficients, h, w, degree)
    residual = relative / smooth - 1.0
    n = residual.size
    var_pixel = float(np.mean(var_relative / smooth ** 2))       # temporal part of the residual's variance
    prnu_var = float(residual.var(ddof=1)) - var_pixel
    prnu = float(np.sqrt(max(prnu_var, 0.0)))
    u_prnu = float(np.hypot(prnu / np.sqrt(2 * (n - 1)), var_pixel * np.sqrt(2 / (n - 1)) / (2 * max(prnu, 1e-12))))
    corners = _design(np.array([-1.0, 1, -1, 1]), np.array([-1.0, -1, 1, 1]), degree).mean(axis=0)
    scatter = float(np.var(b - a @ coefficients, ddof=a.shape[1]))
    cov = scatter * np.linalg.inv(a.T @ a)
    return FlatField(relative.astype(np.float32), float(np.sqrt(np.mean(var_relative))), degree, coefficients,
                     float(corners @ coefficients), float(np.sqrt(corners @ cov @ corners)), prnu, u_prnu)


@dataclass(frozen=True)
class Coefficient:
    """Luminance coefficient k (cd/m² per DN/s) at the centre window and its relative uncertainty budget."""

    cd_m2_per_dn_s: float
    rate_dn_s: float                 # mean signal rate at the centre for the reference luminance
    budget: dict[str, float]         # relative standard uncertainties, k = 1

    @property
    def u_rel(self) -> float:
        return float(np.sqrt(sum(v ** 2 for v in self.budget.values())))


def luminance_coefficient(reference_cd_m2: float, reference_u_rel: float, exposure_s: np.ndarray,
                          centre_signal_dn: np.ndarray, u_centre_signal_dn: np.ndarray, used: np.ndarray,
                          flat: FlatField, centre_pixels: int, exposure_u_rel: float = 0.0) -> Coefficient:
    """k = L_ref / r̄ with r̄ the inverse-variance mean of the centre's rates (signal above dark)/t over the
    linear range, since `rig.physics.hdr` merges exactly such rates.

    Budget: `reference` (the source's stated uncertainty); `noise` (temporal noise of r̄); `linearity` (the
    spread of the rates between exposures, which a campaign's exposure may fall anywhere in); `flat_field`
    (the flat's noise averaged over the centre it is normalised on); `exposure` (realised exposure times)."""
    t = np.asarray(exposure_s, float)[used]
    rates = np.asarray(centre_signal_dn, float)[used] / t
    u_rates = np.asarray(u_centre_signal_dn, float)[used] / t
    weights = u_rates ** -2.0
    rate = float(np.sum(weights * rates) / weights.sum())
    if not rate > 0:
        raise ValueError("the reference source gives no signal above dark at the centre")
    budget = {
        "reference": float(reference_u_rel),
        "noise": float(np.sqrt(1.0 / weights.sum())) / rate,
        "linearity": float(np.std(rates / rate, ddof=1)) if rates.size > 1 else 0.0,
        "flat_field": flat.u_pixel_rel / float(np.sqrt(centre_pixels)),
        "exposure": float(exposure_u_rel),
    }
    return Coefficient(reference_cd_m2 / rate, rate, budget)


@dataclass(frozen=True)
class CalibratedSensorInfo(SensorInfo):
    """SensorInfo of a camera with a calibration file: its coefficient, plus the flat field (H, W) of the
    whole sensor that the merged rate is divided by (`calibration_of`)."""

    flat_field: np.ndarray | None = field(default=None, compare=False, repr=False)

    def flat_of(self, window: Window) -> np.ndarray:
        """The flat field's pixels of a window of the sensor; without one, 1 as a 0-d array (it broadcasts)."""
        if self.flat_field is None:
            return np.ones(())
        return self.flat_field[Window(0, 0, self.width_px, self.height_px).inner(window)]


def calibration_of(sensor: SensorInfo, window: Window) -> np.ndarray:
    """cd/m² per DN/s of the pixels of `window` (float64): the camera's coefficient over its flat field (lens
    fall-off and PRNU), (height, width), where `rig calibrate camera` measured one; else the coefficient
    alone, as a 0-d array (it broadcasts)."""
    if isinstance(sensor, CalibratedSensorInfo):
        return sensor.calibration_cd_m2_per_dn_s / sensor.flat_of(window)
    return np.asarray(sensor.calibration_cd_m2_per_dn_s, dtype=float)
