"""`rig calibrate`: the calibrations of the rig's devices, one subcommand each (`camera`: the radiometric
calibration of a raw camera, docs/camera-calibration.md; `geometry`: the goniometer's, in
rig.cli.calibrate_geometry). This module parses the arguments, opens the device and prints; the procedures
are rig.calibration's. A new subcommand registers in `add_subcommand`.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

import numpy as np

from rig.calibration.radiometric import CalibrationError, measure
from rig.cli.calibrate_geometry import add_geometry
from rig.config.camera_calibration import CameraCalibration, CameraCalibrationError, save_camera_calibration
from rig.config.files import ConfigFileError
from rig.config.rigfile import RigConfig, load_rig_config
from rig.core.errors import DeviceError
from rig.core.exits import EXIT_OK, fail
from rig.drivers.interfaces import LuminanceCamera


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


def add_camera(which: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig calibrate camera --rig RIG.yaml --reference-cd-m2 L --reference-u-rel U --out FILE.yaml`."""
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


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig calibrate` and its subcommands, one line each."""
    calibrate = subparsers.add_parser("calibrate", help="calibrate a device of the rig")
    which = calibrate.add_subparsers(dest="calibrate", required=True)
    add_camera(which)
    add_geometry(which)
