"""`rig calibrate geometry --rig RIG.yaml --out GEOM.yaml`: the geometric calibration of the goniometer with a
ChArUco board (docs/geometry-calibration.md). This module parses the arguments, opens the rig, says what to do
and prints; the procedure is rig.calibration.geometry's, the fit rig.physics.goniometer_fit's.
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from rig.calibration.geometry import GeometryCalibrationError, measure
from rig.config.files import ConfigFileError, parse_model, read_yaml
from rig.config.geometry_calibration import BoardEntry, GeometryCalibration, save_geometry_calibration
from rig.config.rigfile import load_rig_config
from rig.core.errors import DeviceError
from rig.core.exits import EXIT_OK, fail
from rig.physics.charuco_board import BoardError, BoardLayout
from rig.physics.goniometer_fit import calibration_poses
from rig.session.connect import open_rig

#: What the operator is asked to do before each scene (a simulated camera switches its scene instead).
OPERATOR = {"board": "Lay the ChArUco board on the sample holder, its centre on the holder's centre and its rows "
                     "along the sample x mark; light the room.",
            "open": "Take the board off the holder (leave it empty), put the diffuser on the lamp's exit and darken "
                    "the room; the lamp will be switched on.",
            "sample": "The calibration views are done; the board may go."}


def load_board(path: str | None) -> BoardLayout:
    """The board file's layout (docs/geometry-calibration.md), or the default board without one."""
    if path is None:
        return BoardLayout()
    entry = parse_model(read_yaml(path, "board"), BoardEntry, source=path, what="board")
    try:
        return BoardLayout(**entry.model_dump())
    except BoardError as exc:
        raise ConfigFileError(f"{path}: {exc}") from None


def summary(cal: GeometryCalibration) -> str:
    """The table printed after a calibration: every parameter ± its standard uncertainty (k = 1), then the views."""
    lines = [f"geometry calibration of {cal.rig} ({cal.date}); intrinsics RMS {cal.intrinsics.rms_px:.3f} px, "
             f"corners σ {cal.fit.corner_sigma_px:.3f} px, lamp exit σ {cal.fit.lamp_sigma_px:.3f} px"]
    for name, e in cal.parameters.items():
        unit = "m" if name.endswith("_m") else "°"
        lines.append(f"  {name.removesuffix('_deg').removesuffix('_m'):<22} {e.value:+.5f} ± {e.u:.5f} {unit}")
    lines += [f"  pointing {axis} (past the centre) {e.value:+.5f} ± {e.u:.5f} °"
              for axis, e in (("x", cal.pointing_x_deg), ("y", cal.pointing_y_deg))]
    for v in cal.fit.views:
        motors = " ".join(f"{m:7.2f}" for m in v.motors_deg)
        state = f"rejected: {v.rejected}" if v.rejected else f"RMS {v.rms_px:.3f} px"
        lines.append(f"  {v.label:<9} [{motors}]° {v.points:3d} points  {state}")
    return "\n".join(lines)


def _shower(camera: object) -> Callable[[str], None]:
    """How a scene is put before the camera: a simulated camera's scene switch (docs/sim-camera-protocol.md), or
    the operator, asked."""
    switch = getattr(camera, "show", None)
    if callable(switch):
        return switch

    def ask(scene: str) -> None:
        input(f"{OPERATOR[scene.split()[0]]} Press Enter when ready. ")
    return ask


def cmd_geometry(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if not out.parent.is_dir():
        return fail(f"--out {out}: folder {out.parent} does not exist")
    if out.exists():
        return fail(f"--out {out}: exists already; choose another name")
    if args.views < 6 or args.lamp_views < 2:
        return fail(f"--views {args.views} --lamp-views {args.lamp_views}: at least 6 board views and 2 lamp views "
                    "are needed")
    try:
        board = load_board(args.board)
        config = load_rig_config(args.rig)
    except ConfigFileError as exc:
        return fail(str(exc))
    boards, lamps = calibration_poses(args.views, args.lamp_views)
    try:
        with open_rig(config) as devices:
            try:
                cal = measure(devices, config, board, show=_shower(devices.camera),
                              board_poses=boards, lamp_poses=lamps, progress=print)
            finally:
                devices.safe_state()
        save_geometry_calibration(out, cal)
    except (GeometryCalibrationError, DeviceError, ConfigFileError) as exc:
        return fail(f"rig calibrate geometry: {exc}; nothing written")
    print(summary(cal))
    print(f"written {out}; reference it from the rig file as geometry.calibration_file")
    return EXIT_OK


def add_geometry(which: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig calibrate geometry --rig RIG.yaml --out GEOM.yaml [--board BOARD.yaml]`."""
    geometry = which.add_parser("geometry", help="geometric calibration of the goniometer with a ChArUco board")
    geometry.add_argument("--rig", required=True, metavar="RIG.yaml", help="the rig whose goniometer is calibrated")
    geometry.add_argument("--out", required=True, metavar="GEOM.yaml", help="calibration file to write")
    geometry.add_argument("--board", metavar="BOARD.yaml",
                          help="the board's layout (default: 9×7 squares of 20 mm, 12 mm DICT_4X4_50 markers)")
    geometry.add_argument("--views", type=int, default=18, metavar="N", help="board views (default 18)")
    geometry.add_argument("--lamp-views", type=int, default=5, metavar="N",
                          help="views of the lamp's exit, the camera opposite the lamp (default 5)")
    geometry.set_defaults(func=cmd_geometry)
