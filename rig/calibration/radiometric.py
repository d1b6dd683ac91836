"""The radiometric calibration of a raw camera, after EMVA 1288 Release 4.0 with exposure time as the swept
quantity (docs/camera-calibration.md): meter the uniform source, take `frames` full frames of it at exposures
spread evenly up to ~95 % of saturation, then the same exposures with the lens covered; reduce them with
rig.physics.camera_calibration into a rig.config.camera_calibration.CameraCalibration.

The procedure only talks to a LuminanceCamera and a prompt: which camera (the rig's, or a simulated one before
a uniform source) and how the operator is asked are the caller's (`rig calibrate camera`, rig.cli.calibrate).
"""

from __future__ import annotations

import datetime
from collections.abc import Callable

import numpy as np

from rig.config.camera_calibration import (
    CalibratedCamera,
    CameraCalibration,
    CoefficientEntry,
    DarkEntry,
    FlatEntry,
    LinearityEntry,
    PhotonTransferEntry,
    Reference,
)
from rig.core.values import Frame, Window
from rig.drivers.interfaces import CalibratedLuminanceCamera, LuminanceCamera
from rig.physics import camera_calibration as cc
from rig.physics.hdr import saturation_threshold_dn

METHOD = ("EMVA 1288 Release 4.0 Linear: exposure-time sweep at a uniform reference luminance; DSNU, photon "
          "transfer, linearity (5-95 % of saturation), flat field = polynomial fall-off + PRNU")
#: The longest exposure of the sweep puts the brightest centre signal at this fraction of saturation.
TOP_FRACTION = 0.93
#: The shortest exposure of the sweep, as a fraction of the longest.
BOTTOM_FRACTION = 0.03
#: Metering frames at most.
METERING_STEPS = 8


class CalibrationError(Exception):
    """The procedure cannot go on; the message says why and what to do."""


def _meter(camera: LuminanceCamera, centre: Window, threshold: float) -> float:
    """Exposure (s) that puts the centre's brightest pixel at TOP_FRACTION of saturation."""
    s = camera.sensor
    span = threshold - s.black_level_dn
    t = float(np.sqrt(s.min_exposure_s * min(s.max_exposure_s, 1.0)))
    for _ in range(METERING_STEPS):
        peak = float(camera.capture(t, centre).pixels_dn.max()) - s.black_level_dn
        if peak >= span:
            if t <= s.min_exposure_s:
                raise CalibrationError(f"saturated flats: the source saturates the camera even at the shortest "
                                       f"exposure {s.min_exposure_s:g} s; dim it")
            t = max(t / 16, s.min_exposure_s)
            continue
        wanted = t * TOP_FRACTION * span / max(peak, 1.0)
        if wanted > s.max_exposure_s and t >= s.max_exposure_s:
            raise CalibrationError(f"too-dark flats: the longest exposure {s.max_exposure_s:g} s reaches only "
                                   f"{peak / span:.1%} of saturation; brighten the source")
        if peak > 0.2 * span and wanted <= s.max_exposure_s:
            return wanted
        t = min(wanted, s.max_exposure_s)
    raise CalibrationError(f"metering: no exposure found in {METERING_STEPS} frames; is the source steady?")


def sweep(top_s: float, count: int, camera: LuminanceCamera) -> list[float]:
    """`count` exposures evenly spaced from BOTTOM_FRACTION to 1 of `top_s` (EMVA: equidistant steps)."""
    s = camera.sensor
    exposures = np.linspace(BOTTOM_FRACTION, 1.0, count) * top_s
    if exposures[0] < s.min_exposure_s or exposures[-1] > s.max_exposure_s:
        raise CalibrationError(f"exposure range: the sweep {exposures[0]:g}…{exposures[-1]:g} s does not fit the "
                               f"camera's {s.min_exposure_s:g}…{s.max_exposure_s:g} s; dim or brighten the source")
    return [float(e) for e in exposures]


def _stack(take: Callable[[float, Window | None], Frame], exposure_s: float, frames: int) -> tuple[np.ndarray, float]:
    """`frames` full frames of one exposure and the mean exposure time the camera realised."""
    shots = [take(exposure_s, None) for _ in range(frames)]
    return np.stack([f.pixels_dn for f in shots]), float(np.mean([f.exposure_s for f in shots]))


def _signal(flat: cc.StackStats, dark: cc.StackStats, region: tuple[slice, slice]) -> tuple[float, float]:
    """Mean signal above dark over `region` of the mean images, and its standard uncertainty from the
    temporal noise left in them."""
    diff = (flat.mean_dn - dark.mean_dn)[region]
    return float(diff.mean()), float(np.sqrt((flat.var_of_mean_dn2 + dark.var_of_mean_dn2) / diff.size))


def measure(camera: LuminanceCamera, *, reference_cd_m2: float, reference_u_rel: float,
            exposures_s: list[float] | None, frames: int, centre_px: tuple[int, int], prompt: Callable[[str], None],
            shutter: bool, flat_file: str, exposure_u_rel: float = 0.0,
            count: int = 12) -> tuple[CameraCalibration, np.ndarray]:
    """Run the procedure on a raw camera; the calibration (naming its flat field `flat_file`) and the flat
    field. `prompt` tells the operator what to do and returns when it is done; with `shutter` the darks are
    taken with the camera's shutter."""
    if isinstance(camera, CalibratedLuminanceCamera):
        raise CalibrationError(f"{camera.identity()} delivers calibrated luminance: it has its own calibration")
    s = camera.sensor
    if not (0 < centre_px[0] <= s.width_px and 0 < centre_px[1] <= s.height_px):
        raise CalibrationError(f"--window {centre_px[0]} {centre_px[1]}: must fit the "
                               f"{s.width_px}×{s.height_px} sensor")
    centre = Window.centred(s.width_px, s.height_px, *centre_px)
    threshold = saturation_threshold_dn(s)
    prompt(f"Place the uniform source of {reference_cd_m2:g} cd/m² before the lens, filling the field of view.")
    exposures = sorted(exposures_s) if exposures_s else sweep(_meter(camera, centre, threshold), count, camera)
    flats, realised = zip(*(_stack(camera.capture, t, frames) for t in exposures), strict=True)
    prompt("Cover the lens (cap it, in the dark) for the dark frames.")
    darks = [_stack(camera.capture_dark if shutter else camera.capture, t, frames)[0] for t in exposures]
    saturated = np.array([bool(np.any(f >= threshold)) for f in flats])
    if saturated.all():
        raise CalibrationError(f"saturated flats: every exposure from {exposures[0]:g} s saturates; shorten "
                               "--exposures or dim the source")
    identity = CalibratedCamera(identity=camera.identity(), width_px=s.width_px, height_px=s.height_px,
                                bit_depth=s.bit_depth)
    reference = Reference(luminance_cd_m2=reference_cd_m2, u_rel=reference_u_rel)
    try:
        return _reduce(np.array(realised), [cc.stack_stats(f) for f in flats], [cc.stack_stats(d) for d in darks],
                       ~saturated, threshold, centre, reference, exposure_u_rel, identity, flat_file)
    except ValueError as exc:
        raise CalibrationError(f"the frames do not allow a calibration: {exc}") from None


def _reduce(exposures: np.ndarray, flats: list[cc.StackStats], darks: list[cc.StackStats], ok: np.ndarray,
            threshold: float, centre: Window, reference: Reference, exposure_u_rel: float,
            camera: CalibratedCamera, flat_file: str) -> tuple[CameraCalibration, np.ndarray]:
    """The EMVA 1288 reduction of the sweep (`ok`: exposures without saturated pixels); ValueError if the
    frames do not allow it."""
    h, w = flats[0].mean_dn.shape
    whole, in_centre = (slice(None), slice(None)), Window(0, 0, w, h).inner(centre)
    signal, u_signal = np.array([_signal(f, d, whole) for f, d in zip(flats, darks, strict=True)]).T
    centre_signal, u_centre = np.array([_signal(f, d, in_centre) for f, d in zip(flats, darks, strict=True)]).T
    span = threshold - float(np.mean([d.mean_dn.mean() for d in darks]))
    try:
        lin = cc.linearity(exposures[ok], signal[ok], u_signal[ok], span)
    except ValueError as exc:
        raise CalibrationError(f"too-dark flats or too few exposures: {exc}; brighten the source or give "
                               "--exposures reaching higher") from None
    used = np.zeros(exposures.size, bool)
    used[np.flatnonzero(ok)[lin.used]] = True
    deviation = np.full(exposures.size, np.nan)
    deviation[ok] = lin.deviation_rel
    i_flat = int(np.flatnonzero(used)[np.argmin(np.abs(signal[used] - span / 2))])    # nearest half-scale
    flat = cc.flat_field(flats[i_flat], darks[i_flat], centre)
    k = cc.luminance_coefficient(reference.luminance_cd_m2, reference.u_rel, exposures, centre_signal, u_centre,
                                 used, flat, centre.width * centre.height, exposure_u_rel)
    var_signal = np.array([f.temporal_var_dn2 - d.temporal_var_dn2 for f, d in zip(flats, darks, strict=True)])
    ptc = cc.photon_transfer(signal[ok], var_signal[ok], darks[0].temporal_var_dn2, span)
    dark_levels = [cc.dark_level(d, t) for d, t in zip(darks, exposures, strict=True)]
    calibration = CameraCalibration(
        camera=camera,
        date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        method=METHOD, reference=reference,
        coefficient=CoefficientEntry(cd_m2_per_dn_s=k.cd_m2_per_dn_s, u_rel=k.u_rel, budget=k.budget,
                                     centre_window=(centre.x0, centre.y0, centre.width, centre.height)),
        dark=[DarkEntry(exposure_s=d.exposure_s, mean_dn=d.mean_dn, dsnu_dn=d.dsnu_dn,
                        temporal_std_dn=d.temporal_std_dn, frames=d.frames) for d in dark_levels],
        linearity=LinearityEntry(exposures_s=exposures.tolist(), signal_dn=signal.tolist(),
                                 deviation_percent=[None if np.isnan(v) else 100 * v for v in deviation],
                                 le_percent=lin.le_percent, u_le_percent=lin.u_le_percent),
        flat_field=FlatEntry(file=flat_file, exposure_s=exposures[i_flat], prnu_rel=flat.prnu_rel,
                             u_prnu_rel=flat.u_prnu_rel, falloff_degree=flat.degree,
                             falloff_coefficients=flat.coefficients.tolist(), falloff_corner_rel=flat.corner_rel,
                             u_falloff_corner_rel=flat.u_corner_rel),
        photon_transfer=PhotonTransferEntry(gain_dn_per_e=ptc.gain_dn_per_e, u_gain_dn_per_e=ptc.u_gain_dn_per_e,
                                            read_noise_e=ptc.read_noise_e, u_read_noise_e=ptc.u_read_noise_e))
    return calibration, flat.relative
