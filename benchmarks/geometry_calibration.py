"""Benchmark: campaigns on a goniometer with axis zero errors, with and without `rig calibrate geometry`.

On the simulated rig (with its filter wheel) whose four axes carry zero errors drawn with σ 0.3° (30× the
default), the geometry calibration runs (`rig.calibration.geometry.measure`, the board and lamp views rendered by
a camera of a third of the LMK's resolution with the same field of view, on the same goniometer: the zero errors
are drawn before the camera, so they are the same), its file is named by the rig file, and the campaign runs on:

- the same rig with zero errors 0 (the reference), with `geometry.angle_u_deg` 0.01° as typed and with the
  calibrated rig's (a like-for-like budget: the typed 0.01° pads every steep point's u),
- the rig with the zero errors, uncalibrated (`geometry.angle_u_deg` 0.01° as typed),
- the rig with the zero errors and the calibration file (offsets applied, `angle_u_deg` from its covariance),

over several seeds (independent goniometers). The table gives, per campaign and rig, the median and p95
|relative error| of f_r against the closed-form truth at the recorded angles and the k = 2 coverage of the
reported uncertainty; then the calibration's worst offset error and its u.

    python benchmarks/geometry_calibration.py [--seeds N] [--campaign tests/campaigns/e2e-steep.yaml ...]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.error_vs_time import machine  # noqa: E402
from rig.bench.truth import measured_with_truth  # noqa: E402
from rig.calibration.geometry import measure  # noqa: E402
from rig.config.campaign import Campaign, load_campaign  # noqa: E402
from rig.config.geometry_calibration import save_geometry_calibration  # noqa: E402
from rig.config.rigfile import RigConfig, SimulationConfig, load_rig_config, simulated_rig  # noqa: E402
from rig.physics.charuco_board import BoardLayout  # noqa: E402
from rig.physics.geometry import AXIS_NAMES  # noqa: E402
from rig.physics.goniometer_fit import calibration_poses  # noqa: E402
from rig.simulators.rig import SimulatedRig  # noqa: E402

SIGMA_DEG = 0.3
#: The calibration camera: the LMK 98-4 binned 3×3 (same field of view).
SMALL_CAMERA = {"width_px": 464, "height_px": 348, "pixel_pitch_um": 19.35}


def calibrate(rig: RigConfig, folder: Path) -> tuple[Path, float, float]:
    """Run the calibration on `rig`'s goniometer; the file, the worst |offset error| and the largest u (deg)."""
    small = rig.model_copy(update={"camera": rig.camera.model_copy(update=SMALL_CAMERA)})
    boards, lamps = calibration_poses()
    with SimulatedRig(small, "lambert", {"kd": 0.5}) as sim:
        cal = measure(sim.devices, small, BoardLayout(), show=sim.devices.camera.show, board_poses=boards,
                      lamp_poses=lamps)
        truth = np.array([sim.world.axis_zero_deg[name] for name in AXIS_NAMES])
    path = folder / "geometry.yaml"
    save_geometry_calibration(path, cal)
    return path, float(np.max(np.abs(np.array(cal.zero_offsets_deg()) - truth))), max(cal.zero_u_deg())


def calibrated_rig(rig: RigConfig, calibration: Path) -> RigConfig:
    """`rig` as a rig file naming `calibration` would load it (rig.config.rigfile.load_rig_config)."""
    data = rig.model_dump(mode="json")
    data["geometry"] = {k: v for k, v in data["geometry"].items() if k not in ("calibration", "angle_u_deg")}
    data["geometry"]["calibration_file"] = calibration.name
    path = calibration.parent / "rig.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return load_rig_config(path)


def run(campaign: Campaign, rig: RigConfig, out: Path) -> tuple[np.ndarray, np.ndarray]:
    """|relative error| and (f − truth)/u of every point with a value."""
    d, truth = measured_with_truth(campaign, rig, out)
    f, u = d["brdf_per_sr"], d["u_brdf_per_sr"]
    ok = np.isfinite(f) & np.isfinite(u) & (truth > 0)
    return np.abs(f[ok] / truth[ok] - 1), (f[ok] - truth[ok]) / u[ok]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--campaign", nargs="+", default=[str(ROOT / "tests" / "campaigns" / "e2e-steep.yaml")])
    args = parser.parse_args()
    print(machine())
    print(f"simulated rig with its filter wheel; axis zero errors σ {SIGMA_DEG}°, seeds 1…{args.seeds}; calibration "
          f"with the default board (9×7 × 20 mm) and poses ({len(calibration_poses()[0])} board views, "
          f"{len(calibration_poses()[1])} lamp views), camera {SMALL_CAMERA['width_px']}×{SMALL_CAMERA['height_px']}")
    t0 = time.perf_counter()
    rows: dict[tuple[str, str], list[tuple[np.ndarray, np.ndarray]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for seed in range(1, args.seeds + 1):
            folder = Path(tmp) / f"seed{seed}"
            folder.mkdir()
            erring = simulated_rig().model_copy(update={"simulation": SimulationConfig(
                seed=seed, axis_zero_sigma_deg=SIGMA_DEG)})
            calibration, worst, u = calibrate(erring, folder)
            print(f"seed {seed}: calibration's worst |offset error| {worst:.4f}°, largest u {u:.4f}°", flush=True)
            calibrated = calibrated_rig(erring, calibration)
            exact = simulated_rig().model_copy(update={"simulation": SimulationConfig(seed=seed,
                                                                                      axis_zero_sigma_deg=0.0)})
            rigs = {"no zero errors": exact,
                    "no zero errors, u as cal.": exact.model_copy(update={"geometry": exact.geometry.model_copy(
                        update={"angle_u_deg": calibrated.geometry.angle_u_deg})}),
                    f"σ {SIGMA_DEG}°, uncalibrated": erring,
                    f"σ {SIGMA_DEG}°, calibrated": calibrated}
            for path in args.campaign:
                campaign = load_campaign(path)
                for label, rig in rigs.items():
                    out = folder / f"{campaign.name}-{label}".replace(" ", "_").replace("°", "").replace(",", "")
                    rows.setdefault((campaign.name, label), []).append(run(campaign, rig, out))
    print(f"{'campaign':16s} {'rig':26s} {'points':>6s} {'med|rel|':>8s} {'p95|rel|':>8s} {'cov k=2':>7s}")
    for (name, label), results in rows.items():
        rel = np.concatenate([r[0] for r in results])
        z = np.concatenate([r[1] for r in results])
        print(f"{name:16s} {label:26s} {rel.size:6d} {np.median(rel):8.4f} {np.percentile(rel, 95):8.4f} "
              f"{np.mean(np.abs(z) <= 2):7.3f}")
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
