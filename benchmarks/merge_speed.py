"""Benchmark: the full-frame HDR merge against a copy of its frames, and a campaign with images saved.

Wall time depends on the machine and its load, so each figure is printed with a baseline
measured in the same run (issue 17's targets are printed next to them; the script reports,
it does not fail):

- merge: `merge_exposures` (the rig's: the compiled kernel where the install built it), its
  numpy fallback and `merge_exposures_reference` (its float64 definition) on 3 exposures of a
  full simulated frame, against a plain copy of the same frames; best of --repeat. Targets:
  ≤ 20 ms and ≤ 60× the copy. Also the first call in a fresh process (importing
  `rig.physics.hdr`, then the first merge, which imports OpenCV for the dark's median),
  the cost a `rig run` pays once.
- campaign: campaigns/quick.yaml run with `capture.save_images: true` and without, each
  into a temporary folder through `rig run`, --campaign-runs times alternating (a 1.4 s run
  varies by 10 % here), the best of each reported. Target: ≤ 3× the wall time without images. Then
  where a point's time goes in each (SPLIT: the simulated scene and sensor, the reduction, the
  EXR files), so that what is left to make faster is measured, not guessed.

    python benchmarks/merge_speed.py [--repeat N] [--campaign-runs N] [--skip-campaign]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.acquisition.capture import Acquisition  # noqa: E402
from rig.bench.error_vs_time import best_of, machine  # noqa: E402
from rig.cli.main import main as rig_main  # noqa: E402
from rig.config.rigfile import RigConfig  # noqa: E402
from rig.core.bands import workers  # noqa: E402
from rig.physics import hdr  # noqa: E402
from rig.physics.hdr import merge_exposures, merge_exposures_reference  # noqa: E402
from rig.simulators.camera import SimCamera, lit_view  # noqa: E402
from rig.simulators.sensor import SensorModel  # noqa: E402
from rig.simulators.texture import GlintTexture  # noqa: E402

EXPOSURES_S = (0.001, 0.004, 0.016)
MERGE_TARGET_S = 20e-3
MERGE_TARGET_COPIES = 60.0
IMAGES_TARGET_RATIO = 3.0
CAMPAIGN = ROOT / "campaigns" / "quick.yaml"


def frames(cfg: RigConfig) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Raw frames and darks (1, H, W) of a full frame, uint16: a log-normal scene over 4 decades, so that
    the bracket has saturated and clipped pixels, EMVA 1288 noise as the simulated sensor draws it."""
    cam = cfg.camera
    rng = np.random.default_rng(0)
    shape = (cam.height_px, cam.width_px)
    rate_e_s = rng.lognormal(np.log(3e5), 2.0, shape)

    def expose(rate: np.ndarray | float, t: float) -> np.ndarray:
        electrons = rng.poisson((rate + cfg.simulation.dark_current_e_s) * t) + rng.normal(0.0, cam.read_noise_e, shape)
        dn = np.rint(cam.black_level_dn + cam.gain_dn_per_e * electrons)
        return np.clip(dn, 0, 2 ** cam.bit_depth - 1).astype(np.uint16)[None]
    return [expose(rate_e_s, t) for t in EXPOSURES_S], [expose(0.0, t) for t in EXPOSURES_S]


#: Run in a fresh interpreter on frames saved by `first_call_s`: prints the import and first-merge times (s).
FIRST_CALL = """
import json, sys, time
import numpy as np
saved = np.load(sys.argv[1])
stacks = [saved[f"arr_{k}"] for k in range(len(saved.files))]
raw, darks = stacks[:len(stacks) // 2], stacks[len(stacks) // 2:]
start = time.perf_counter()
from rig.physics.hdr import merge_exposures
import_s = time.perf_counter() - start
from rig.config.rigfile import RigConfig
sensor = RigConfig().camera.sensor_info()
start = time.perf_counter()
merge_exposures(raw, darks, json.loads(sys.argv[2]), sensor)
print(json.dumps({"import_s": import_s, "first_merge_s": time.perf_counter() - start}))
"""


def first_call_s(raw: list[np.ndarray], darks: list[np.ndarray]) -> dict[str, float]:
    """Import and first-merge times (s) of `rig.physics.hdr` in a fresh process, on these frames."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "frames.npz"
        np.savez(path, *raw, *darks)                                      # arr_0 … arr_{2E−1}: frames, then darks
        done = subprocess.run([sys.executable, "-c", FIRST_CALL, str(path), json.dumps(EXPOSURES_S)], cwd=ROOT,
                              capture_output=True, text=True, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def merge_figures(repeat: int) -> None:
    cfg = RigConfig()
    raw, darks = frames(cfg)
    sensor = cfg.camera.sensor_info()
    copy = best_of(lambda: [f.copy() for f in raw], repeat)
    merge_exposures(raw, darks, EXPOSURES_S, sensor)                  # warm-up: the histogram's import
    fast = best_of(lambda: merge_exposures(raw, darks, EXPOSURES_S, sensor), repeat)
    reference = best_of(lambda: merge_exposures_reference(raw, darks, EXPOSURES_S, sensor), max(repeat // 4, 2))
    kernel, hdr._merge_kernel = hdr._merge_kernel, None       # the numpy merge of an install without a C compiler
    fallback = best_of(lambda: merge_exposures(raw, darks, EXPOSURES_S, sensor), max(repeat // 4, 2))
    hdr._merge_kernel = kernel
    first = first_call_s(raw, darks)
    print(f"merge of {len(raw)} exposures of {cfg.camera.width_px}×{cfg.camera.height_px} (best of {repeat}):")
    print(f"  copy of the frames       {copy * 1e3:8.2f} ms")
    print(f"  reference merge          {reference * 1e3:8.2f} ms   {reference / fast:6.1f}× the fast merge")
    print(f"  numpy merge (no C build) {fallback * 1e3:8.2f} ms   {fallback / fast:6.1f}× the fast merge")
    label = f"fast merge, {'compiled' if kernel else 'numpy'}"
    print(f"  {label:<24s} {fast * 1e3:8.2f} ms   {fast / copy:6.1f}× the copy on {workers()} CPUs   "
          f"targets ≤ {MERGE_TARGET_S * 1e3:.0f} ms, ≤ {MERGE_TARGET_COPIES:.0f}× the copy"
          f"{'' if fast <= MERGE_TARGET_S and fast / copy <= MERGE_TARGET_COPIES else '  (missed)'}")
    print(f"  fresh process: import    {first['import_s'] * 1e3:8.2f} ms   then first merge "
          f"{first['first_merge_s'] * 1e3:.2f} ms = {first['first_merge_s'] / fast:.1f}× the fast merge")


#: Where a point's wall time goes, timed in both campaigns: (owner, attribute, label). Nested: the scene's
#: parts are inside the scene, the merge inside the reduction.
SPLIT = ((SimCamera, "_render_scene", "simulated scene (rays, BRDF, texture)"),
         (GlintTexture, "__call__", "  of which the glint texture"),
         (lit_view.__module__, "lit_view", "  of which the rays (lit_view)"),
         (SensorModel, "read", "simulated sensor (noise, digitising)"),
         (Acquisition, "reduce", "reduction (merge, ROI, flat field)"),
         ("rig.acquisition.capture", "merge_exposures", "  of which the merge"),
         ("rig.acquisition.capture", "merged_rate", "  of which the merge"),
         ("rig.data.dataset_writer", "write_luminance_exr", "EXR files written"))


@contextmanager
def time_spent(targets: Sequence[tuple[object, str, str]]) -> Iterator[Counter[str]]:
    """Wall time (s) spent inside each target, summed by label, while the block runs (the targets are
    wrapped for its duration; a module is named by its import path)."""
    owners = [sys.modules[o] if isinstance(o, str) else o for o, _, _ in targets]
    originals = [getattr(owner, name) for owner, (_, name, _) in zip(owners, targets)]
    spent: Counter[str] = Counter()

    def timed(original: Callable[..., Any], label: str) -> Callable[..., Any]:
        def wrapped(*args: Any, **kwargs: Any) -> Any:
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                spent[label] += time.perf_counter() - start
        return wrapped
    for owner, original, (_, name, label) in zip(owners, originals, targets):
        setattr(owner, name, timed(original, label))
    try:
        yield spent
    finally:
        for owner, original, (_, name, _) in zip(owners, originals, targets):
            setattr(owner, name, original)


def campaign_wall(save_images: bool, folder: Path) -> tuple[float, Counter[str]]:
    """Wall time (s) of `rig run` on the quick campaign with save_images set as asked, and its SPLIT."""
    campaign = yaml.safe_load(CAMPAIGN.read_text())
    campaign.setdefault("capture", {})["save_images"] = save_images
    folder.mkdir(exist_ok=True)
    path = folder / f"quick_images_{save_images}.yaml"
    path.write_text(yaml.safe_dump(campaign))
    with time_spent(SPLIT) as spent:
        start = time.perf_counter()
        code = rig_main(["run", str(path), "--out", str(folder / f"run_{save_images}"), "--quiet"])
        wall = time.perf_counter() - start
    if code != 0:
        raise SystemExit(f"rig run exited with {code}")
    return wall, spent


def campaign_figures(runs: int) -> None:
    """Each campaign `runs` times, alternating; the best wall time of each (and its split) is reported."""
    best: dict[bool, tuple[float, Counter[str]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for run in range(runs):
            for images in (False, True):
                wall, split = campaign_wall(images, Path(tmp) / str(run))
                if images not in best or wall < best[images][0]:
                    best[images] = wall, split
        n_images = len(list((Path(tmp) / "0" / "run_True" / "images").glob("*.exr")))
    (without, split_without), (with_images, split_with) = best[False], best[True]
    ratio = with_images / without
    print(f"quick campaign ({n_images} images), best of {runs} runs each:")
    print(f"  without images           {without:8.2f} s")
    print(f"  with images saved        {with_images:8.2f} s   {ratio:6.2f}× without   "
          f"target ≤ {IMAGES_TARGET_RATIO:.0f}×{'' if ratio <= IMAGES_TARGET_RATIO else '  (missed)'}")
    per_point = 1e3 / max(n_images, 1)
    print(f"  where it goes, ms per point, without → with images (extra {(with_images - without) * per_point:.0f}):")
    for label in dict.fromkeys(label for _, _, label in SPLIT):
        print(f"    {label:<40s} {split_without[label] * per_point:7.1f} → {split_with[label] * per_point:7.1f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=20, help="runs per merge figure; the best is reported")
    ap.add_argument("--skip-campaign", action="store_true", help="only the merge figures")
    ap.add_argument("--campaign-runs", type=int, default=3, help="runs of each campaign; the best is reported")
    args = ap.parse_args()
    print(f"machine : {machine()}")
    merge_figures(args.repeat)
    if not args.skip_campaign:
        campaign_figures(args.campaign_runs)
    return 0


if __name__ == "__main__":
    sys.exit(main())
