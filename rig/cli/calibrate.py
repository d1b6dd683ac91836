"""`rig calibrate camera`: radiometric calibration of a raw camera (docs/camera-calibration.md).

The procedure, after EMVA 1288 Release 4.0 with exposure time as the swept quantity: meter the uniform
source, take `frames` full frames of it at exposures spread evenly up to ~95 % of saturation, then the
same exposures with the lens covered; reduce them with rig.physics.camera_calibration and write the
calibration file (rig.config.camera_calibration). On the simulated rig the camera looks at a simulated
uniform source and the darks are taken with its shutter, without prompts.
"""

from __future__ import annotations

import argparse
import datetime
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rig.config.camera_calibration import (
    CalibratedCamera,
    CameraCalibration,
    CameraCalibrationError,
    CoefficientEntry,
    DarkEntry,
    FlatEntry,
    LinearityEntry,
    PhotonTransferEntry,
    Reference,
    save_camera_calibration,
)
from rig.config.files import ConfigFileError
from rig.config.rigfile import RigConfig, load_rig_config
from rig.core.errors import DeviceError
from rig.core.exits import EXIT_OK, fail
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


def summary(cal: CameraCalibration) -> str:
    """The table printed after a calibration: value ± standard uncertainty (k = 1)."""
    k, f, lin, ptc = cal.coefficient, cal.flat_field, cal.linearity, cal.photon_transfer
    lines = [f"camera {cal.camera.identity}: {cal.camera.width_px}×{cal.camera.height_px}, "
             f"{len(lin.exposures_s)} exposures {lin.exposures_s[0]:.4g}…{lin.exposures_s[-1]:.4g} s",
             f"  coefficient k        {k.cd_m2_per_dn_s:.6g} cd/m² per DN/s ± {100 * k.u_rel:.3f} %"]
    lines += [f"    u_rel {name:<12} {100 * v:.4f} %" for name, v in k.budget.items()]
    lines += [f"  linearity error LE   {lin.le_percent:.3f} % ± {lin.u_le_percent:.3f} %",
              f"  PRNU                 {100 * f.prnu_rel:.3f} % ± {100 * f.u_prnu_rel:.3f} %",
              f"  fall-off at corners  {f.falloff_corner_rel:.4f} ± {f.u_falloff_corner_rel:.4f} of the centre"]
    if ptc is not None:
        lines += [f"  gain K               {ptc.gain_dn_per_e:.4g} ± {ptc.u_gain_dn_per_e:.2g} DN/e⁻",
                  f"  dark noise σd        {ptc.read_noise_e:.3g} ± {ptc.u_read_noise_e:.2g} e⁻"]
    lines += [f"  dark {d.exposure_s:9.4g} s     mean {d.mean_dn:8.2f} DN, DSNU {d.dsnu_dn:6.3f} DN, "
              f"σ {d.temporal_std_dn:6.3f} DN" for d in (cal.dark[0], cal.dark[-1])]
    return "\n".join(lines)


def _open_camera(config: RigConfig, reference_cd_m2: float) -> tuple[LuminanceCamera, Callable[[], None]]:
    """The rig's camera alone, and how to close it: on the simulated rig a simulated camera before a
    uniform source of the reference luminance."""
    if config.simulated:
        from rig.physics.brdf_models import get_model
        from rig.simulators.camera import UniformSourceCamera
        from rig.simulators.world import SimWorld

        sim = UniformSourceCamera(SimWorld(config, get_model("lambert"), {"kd": 0.5}), reference_cd_m2)
        return sim, sim.close
    from rig.devices import connect_camera
    from rig.drivers.wallclock import WallClock

    camera = connect_camera(config, WallClock(config.time_scale))
    return camera, camera.close


def _no_prompt(text: str) -> None:
    """The simulated rig needs no operator."""


def _ask_operator(text: str) -> None:
    input(f"{text} Press Enter when ready. ")


def cmd_camera(args: argparse.Namespace, prompt: Callable[[str], None] | None = None) -> int:
    out = Path(args.out)
    sidecar = out.with_suffix(".flat.npy")
    if not out.parent.is_dir():
        return fail(f"--out {out}: folder {out.parent} does not exist")
    for target in (out, sidecar):
        if target.exists():
            return fail(f"--out {out}: {target} exists already; choose another name")
    if not (np.isfinite(args.reference_cd_m2) and args.reference_cd_m2 > 0):
        return fail(f"--reference-cd-m2 {args.reference_cd_m2:g}: must be a positive luminance")
    if not 0 <= args.reference_u_rel < 1:
        return fail(f"--reference-u-rel {args.reference_u_rel:g}: must be a relative uncertainty in [0, 1)")
    if args.frames < 2:
        return fail(f"--frames {args.frames}: at least two frames per exposure are needed for temporal noise")
    if args.exposures is not None and (len(args.exposures) < 3 or min(args.exposures) <= 0):
        return fail("--exposures: give at least three positive exposure times (s)")
    try:
        config = load_rig_config(args.rig)
    except ConfigFileError as exc:
        return fail(str(exc))
    ask = prompt or (_no_prompt if config.simulated else _ask_operator)
    try:
        camera, close = _open_camera(config, args.reference_cd_m2)
        try:
            cal, flat = measure(camera, reference_cd_m2=args.reference_cd_m2, reference_u_rel=args.reference_u_rel,
                                exposures_s=args.exposures, frames=args.frames, centre_px=tuple(args.window),
                                prompt=ask, shutter=config.simulated, flat_file=sidecar.name,
                                exposure_u_rel=args.exposure_u_rel)
        finally:
            close()
        save_camera_calibration(out, cal, flat)
    except (CalibrationError, DeviceError, CameraCalibrationError, ConfigFileError) as exc:
        return fail(f"rig calibrate camera: {exc}")
    print(summary(cal))
    print(f"written {out} and {sidecar.name}; reference it from the rig file as "
          f"camera.calibration_file")
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig calibrate camera --rig RIG.yaml --reference-cd-m2 L --reference-u-rel U --out FILE.yaml`."""
    calibrate = subparsers.add_parser("calibrate", help="calibrate a device of the rig")
    which = calibrate.add_subparsers(dest="calibrate", required=True)
    camera = which.add_parser("camera", help="radiometric calibration of a raw camera (EMVA 1288)")
    camera.add_argument("--rig", required=True, metavar="RIG.yaml", help="the rig whose camera is calibrated")
    camera.add_argument("--reference-cd-m2", type=float, required=True, metavar="L",
                        help="luminance of the uniform source at the centre of the view (cd/m²)")
    camera.add_argument("--reference-u-rel", type=float, required=True, metavar="U",
                        help="its relative standard uncertainty (k = 1), from its certificate")
    camera.add_argument("--out", required=True, metavar="FILE.yaml",
                        help="calibration file to write (with FILE.flat.npy beside it)")
    camera.add_argument("--exposures", type=float, nargs="+", metavar="S",
                        help="exposure times (s) of the sweep (default: 12 up to ~93 %% of saturation, metered)")
    camera.add_argument("--frames", type=int, default=8, help="frames per exposure, light and dark (default 8)")
    camera.add_argument("--window", type=int, nargs=2, default=(70, 70), metavar=("W", "H"),
                        help="central window (px) where k holds and the flat field is 1 (default 70 70)")
    camera.add_argument("--exposure-u-rel", type=float, default=0.0, metavar="U",
                        help="relative standard uncertainty of realised exposure times (default 0)")
    camera.set_defaults(func=cmd_camera)
