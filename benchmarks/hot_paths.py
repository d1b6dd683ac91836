"""Benchmark: wall time of the hot paths that used to be asserted in tests.

Wall time depends on the machine and its load, so it is measured here, never in the test
suite. Each figure is the best of --repeat runs and is printed with its ratio to a baseline
measured in the same run: a plain copy of one full camera frame (1390 × 1040 float64), so that
the ratios can be compared between machines. The former test thresholds are printed as the
targets; the script reports, it does not fail.

    python benchmarks/hot_paths.py [--repeat N]

- simulated camera: one 10 ms capture of the campaigns' 70 px ROI window, of the full frame,
  and the glints' share of the ROI capture (the same capture with the glint texture off);
- optics: `roi_inside_spot` for 3000 random poses (the planner's `roi_unlit` check);
- geometry: `inverse_deg` and `forward_deg` on 100,000 requests (planning a large campaign).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.error_vs_time import best_of, machine  # noqa: E402
from rig.config.rigfile import RigConfig, camera_optics  # noqa: E402
from rig.core.values import Window  # noqa: E402
from rig.physics.brdf_models import get_model  # noqa: E402
from rig.physics.geometry import forward_deg, inverse_deg  # noqa: E402
from rig.physics.optics import roi_inside_spot  # noqa: E402
from rig.simulators.camera import SimCamera  # noqa: E402
from rig.simulators.world import SimWorld  # noqa: E402

ROI_PX = 70
EXPOSURE_S = 0.01
N_POSES = 3000
N_REQUESTS = 100_000


def lit_camera(cfg: RigConfig) -> SimCamera:
    """The simulated camera on a lit, textured Lambertian sample at (θi, φi, θo, φo) = (30, 0, 20, 90)."""
    world = SimWorld(cfg, get_model("lambert"), {"kd": 0.5})
    world.lamp.set_current(cfg.lamp.current_a, 0)
    world.lamp.switch(True)
    for name, value in zip(("stage_vertical", "stage_normal", "arm_azimuth", "arm_polar"),
                           inverse_deg(30.0, 0.0, 20.0, 90.0).as_array()):
        world.axis_truth[name] = lambda value=float(value): value
    return SimCamera(world)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20, help="runs per figure; the best is reported")
    args = ap.parse_args()
    cfg = RigConfig()
    cam = lit_camera(cfg)
    optics = camera_optics(cfg)
    roi = Window.centred(optics.width_px, optics.height_px, ROI_PX, ROI_PX)
    frame = np.random.default_rng(0).random((optics.height_px, optics.width_px))
    rng = np.random.default_rng(1)
    poses = tuple(np.radians(inverse_deg(*rng.uniform([0, 0, 0, 0], [85, 360, 89, 360], (N_POSES, 4)).T)
                             .as_array()).T)
    requests = [rng.uniform(0, hi, N_REQUESTS) for hi in (90, 360, 90, 360)]
    motors = inverse_deg(*requests).as_array()

    print(f"machine : {machine()}")
    print(f"settings: best of {args.repeat}; camera {optics.width_px}×{optics.height_px}, ROI {ROI_PX} px, "
          f"exposure {EXPOSURE_S * 1e3:.0f} ms; {N_POSES} poses; {N_REQUESTS} kinematics requests")
    baseline = best_of(frame.copy, args.repeat)
    print(f"baseline: plain copy of a full frame {baseline * 1e3:.3f} ms\n")

    figures = [("camera: ROI capture", lambda: cam.capture(EXPOSURE_S, roi), 2e-3),
               ("camera: full-frame capture", lambda: cam.capture(EXPOSURE_S), 0.5),
               ("optics: roi_inside_spot", lambda: roi_inside_spot(*poses, ROI_PX, optics,
                                                                   cfg.geometry.spot_diameter_m / 2), 10e-3),
               ("geometry: inverse_deg", lambda: inverse_deg(*requests, current_deg=(10.0, 20.0, 30.0, 40.0)), 1.0),
               ("geometry: forward_deg", lambda: forward_deg(*motors.T), 1.0)]
    print(f"{'hot path':30s} {'ms':>10s} {'× baseline':>11s} {'target ms':>10s}")
    walls = {}
    for label, fn, target_s in figures:
        fn()                                                         # warm-up: caches, lazy tables
        walls[label] = wall = best_of(fn, args.repeat)
        print(f"{label:30s} {wall * 1e3:10.3f} {wall / baseline:11.2f} {target_s * 1e3:10.1f}"
              f"{'' if wall <= target_s else '  (slower than target)'}")
    cam.glint = lambda *_: 1.0
    no_glints = best_of(lambda: cam.capture(EXPOSURE_S, roi), args.repeat)
    share = walls["camera: ROI capture"] - no_glints
    print(f"{'camera: glints share of ROI':30s} {share * 1e3:10.3f} {share / baseline:11.2f} {1.0:10.1f}"
          f"{'' if share <= 1e-3 else '  (slower than target)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
