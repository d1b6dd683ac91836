"""Study: the error of averaging a curved BRDF lobe over the ROI's angular footprint (issue 13, item 3).

For a glossy modified-Phong sample (n = 3000 and 10000, peak ≥ 300 sr⁻¹) at a few incidences, with views
across the specular lobe (peak, flanks 0.5–5° off, off-lobe), and for diffuse and retroreflective samples,
the simulated camera captures each view (rig.acquisition.capture, the campaigns' 70 px ROI) and the script
prints, per case, the relative error of the ROI luminance against the true BRDF at the ROI centre and
z = error / u, for the plain ROI mean (u: block spread ⊕ calibration) and for the lobe-corrected value
(rig.physics.footprint; u: block spread about the lobe ⊕ lobe fit ⊕ calibration). Only the camera's part
is studied: E⊥ is the simulation's true one (lamp drift and warm-up off), so z has no E⊥ or angle part.

    python benchmarks/footprint_study.py [--seeds N]

The camera's responsivity is lowered so that the glossy peak does not saturate the shortest exposure
(saturation is handled elsewhere). Summary lines give, per sample, the median |relative error|, the
largest |error|, and the fraction of |z| ≤ 2, for both estimates.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.acquisition.capture import RawCapturer  # noqa: E402
from rig.config.capture import CaptureSettings  # noqa: E402
from rig.config.rigfile import CameraConfig, RigConfig, SimulationConfig, camera_optics  # noqa: E402
from rig.core.values import Window  # noqa: E402
from rig.physics.brdf_models import get_model  # noqa: E402
from rig.physics.footprint import view_footprint_deg  # noqa: E402
from rig.physics.geometry import AXIS_NAMES, directions_scs, inverse_deg  # noqa: E402
from rig.physics.roi import block_means, u_mean_of_blocks  # noqa: E402
from rig.simulators.camera import SimCamera  # noqa: E402
from rig.simulators.world import SimWorld  # noqa: E402

RETRO = {"kd": 0.701, "n": 68.0, "k1": 0.184, "k2": 1.53e-12, "k3": 0.00570, "k4": 3.40}   # e2e-steep (RM3)
#: (label, model, params, responsivity e/(cd/m²·s)): peak (n+2)/(2π)·ks = 382 and 318 sr⁻¹.
SAMPLES = [
    ("phong n=3000", "modified_phong", {"kd": 0.05, "ks": 0.8, "n": 3000.0}, 3.0),
    ("phong n=10000", "modified_phong", {"kd": 0.05, "ks": 0.2, "n": 10000.0}, 3.0),
    ("lambert", "lambert", {"kd": 0.5}, 900.0),
    ("retrophong", "retrophong", RETRO, 900.0),
]
INCIDENCES = (20.0, 45.0, 60.0)
#: View offsets (deg of θo from the mirror direction): peak, flanks, off-lobe.
OFFSETS = (0.0, 0.25, 0.5, -0.5, 1.0, 1.5, -1.5, 2.0, 3.0, 5.0, 15.0)


def world_for(model: str, params: dict, responsivity: float, seed: int) -> SimWorld:
    sim = SimulationConfig(seed=seed, warmup_amplitude=0.0, drift_per_hour=0.0)
    world = SimWorld(RigConfig(camera=CameraConfig(responsivity_e_per_cd_m2_s=responsivity), simulation=sim),
                     get_model(model), params)
    world.lamp.set_current(world.config.lamp.current_a, 0)
    world.lamp.switch(True)
    return world


def measure(world: SimWorld, capturer: RawCapturer,
            angles: tuple[float, ...]) -> tuple[float, float, float, float, tuple[str, ...]] | None:
    """(error, z) of the plain ROI mean and of the corrected value at BRDF angles, and the point's flags."""
    motors = inverse_deg(*angles).as_array()
    if not np.all(np.isfinite(motors)):
        return None
    for name, value in zip(AXIS_NAMES, motors):
        world.axis_truth[name] = lambda value=float(value): value
    acq = capturer.acquire()
    cap = acq.reduce()
    if cap.saturated_fraction > 0 or "low_signal" in cap.flags:
        return None
    wi, wo = directions_scs(*np.radians(motors))
    e_surface = world.illuminance_normal_lx() * wi[2]
    truth = float(world.brdf(wi, wo)) * e_surface
    lum = acq.roi_merge.rate_dn_s * acq.sensor.calibration_cd_m2_per_dn_s
    u_cal = acq.sensor.calibration_u_rel
    plain, u_plain = float(lum.mean()), u_mean_of_blocks(block_means(lum))
    u_plain = float(np.hypot(u_plain, u_cal * plain))
    return ((plain - truth) / truth, (plain - truth) / u_plain,
            (cap.luminance_cd_m2 - truth) / truth, (cap.luminance_cd_m2 - truth) / cap.u_luminance_cd_m2, cap.flags)


def study(seeds: int) -> None:
    settings = CaptureSettings(dark_max_age_s=None)      # darks taken once per world, as they always were
    rig = RigConfig()
    roi = Window.centred(rig.camera.width_px, rig.camera.height_px, settings.roi_px, settings.roi_px)
    print(f"ROI {settings.roi_px} px: view footprint (half-angle) {view_footprint_deg(camera_optics(rig), roi):.3f}°,"
          " illumination footprint 0° (collimated beam)")
    print(f"{'sample':14s} {'θi':>4s} {'Δθo':>5s} | {'plain err':>9s} {'z':>6s} | {'lobe err':>9s} {'z':>6s} | flags")
    for label, model, params, responsivity in SAMPLES:
        rows = []
        for seed in range(1, seeds + 1):
            world = world_for(model, params, responsivity, seed)
            capturer = RawCapturer(SimCamera(world), settings, world.clock)
            for theta_i in INCIDENCES:
                for offset in OFFSETS:
                    theta_o = theta_i + offset
                    if not 0 <= theta_o < 80:
                        continue
                    # diffuse/retro samples: the same views; the retro lobe is on the lamp's side
                    result = measure(world, capturer, (theta_i, 0.0, theta_o, 180.0))
                    if result is None:
                        continue
                    rows.append(result[:4])
                    if seed == 1:
                        print(f"{label:14s} {theta_i:4.0f} {offset:+5.2f} | {result[0]:+9.4f} {result[1]:+6.2f} |"
                              f" {result[2]:+9.4f} {result[3]:+6.2f} | {';'.join(result[4])}")
        a = np.array(rows)
        print(f"== {label}: {len(a)} points; plain: median |err| {np.median(np.abs(a[:, 0])):.4f},"
              f" max {np.max(np.abs(a[:, 0])):.3f}, |z|≤2 {np.mean(np.abs(a[:, 1]) <= 2):.3f};"
              f" corrected: median |err| {np.median(np.abs(a[:, 2])):.4f}, max {np.max(np.abs(a[:, 2])):.3f},"
              f" |z|≤2 {np.mean(np.abs(a[:, 3]) <= 2):.3f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="independent simulated samples per case")
    study(parser.parse_args().seeds)


if __name__ == "__main__":
    main()
