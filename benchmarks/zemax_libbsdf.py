"""The Zemax export read by libbsdf, an independent open-source reader (issue 37; opt-in: needs a C++ toolchain).

    python benchmarks/zemax_libbsdf.py --libbsdf SRC [--sim-seed 1]

SRC is a checkout of github.com/KimuraRyo/libbsdf (MPL 2.0; it needs CMake ≥ 3.22, a C++17 compiler and Eigen 3,
e.g. Debian's libeigen3-dev). The library is built into SRC/build once (library only, no OpenMP), and
benchmarks/libbsdf/zemax_probe.cpp, our few lines over its `ZemaxBsdfReader` and `computeReflectance`, beside it.
Then, for

- the export of an MRM + Lambert fit (the test's: kd 0.3, roughness 0.23, F0 0.19) against the model,
- the export from the data of the reduced end-to-end campaign and of the paper campaign against the simulated truth,

libbsdf's value at 3000 random directions (θi 0.5–84°) against the truth (median relative error; the issue's bounds:
3 % from a fit, 12 % from data), and libbsdf's albedo at the paper's incidences (0–80° by 10°, 85°; a few on and
between rows for the fit) against the truth's and against the file's own TIS line (the table's integral on its
grid).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.error_vs_time import machine  # noqa: E402
from rig.cli.main import main as rig  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.physics.brdf_models import albedo, get_model  # noqa: E402

PROBE_SOURCE = ROOT / "benchmarks" / "libbsdf" / "zemax_probe.cpp"
FIT = {"model": "mrm_diffuse", "params": {"kd": 0.3, "roughness": 0.23, "f0": 0.19}}
PAPER_INCIDENCES = [0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0, 85.0]
CAMPAIGNS = [ROOT / "tests" / "campaigns" / "e2e-reduced.yaml", ROOT / "campaigns" / "spieringhs2023-rm1.yaml"]


def build_probe(src: Path) -> Path:
    build = src / "build"
    if not (build / "liblibbsdf.a").exists():
        subprocess.run(["cmake", "-S", str(src), "-B", str(build), "-DCMAKE_BUILD_TYPE=Release",
                        "-DLIBBSDF_BUILD_APPLICATIONS=OFF", "-DLIBBSDF_USE_OPENMP=OFF"], check=True)
        subprocess.run(["make", "-C", str(build), "libbsdf"], check=True)
    probe = build / "zemax_probe"
    subprocess.run(["g++", "-O2", "-DNDEBUG", "-std=c++17", "-I", str(src / "include"), "-I", "/usr/include/eigen3",
                    str(PROBE_SOURCE), str(build / "liblibbsdf.a"), "-o", str(probe)], check=True)
    return probe


def ask(probe: Path, bsdf: Path, queries: list[str]) -> np.ndarray:
    out = subprocess.run([str(probe), str(bsdf)], input="\n".join(queries) + "\n", capture_output=True, text=True,
                         check=True).stdout
    return np.array(out.split(), float)


def tis_lines(bsdf: Path) -> tuple[np.ndarray, np.ndarray]:
    """The file's incidences and TIS lines (read the plain way: the lines after `AngleOfIncidence` and `TIS`)."""
    lines = bsdf.read_text(encoding="ascii").splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("AngleOfIncidence"))
    return np.array(lines[k + 1].split(), float), np.array([float(line.split()[1]) for line in lines
                                                             if line.startswith("TIS")])


def compare(name: str, probe: Path, bsdf: Path, model: str, params: dict[str, float], incidences: list[float]) -> None:
    rng = np.random.default_rng(37)
    n = 3000
    theta_i = rng.uniform(0.5, 84.0, n)
    mu, phi = rng.uniform(0.02, 1.0, n), rng.uniform(0, 2 * np.pi, n)
    wo = np.stack([np.sqrt(1 - mu ** 2) * np.cos(phi), np.sqrt(1 - mu ** 2) * np.sin(phi), mu], axis=-1)
    t = np.radians(theta_i)[:, None]
    wi = np.concatenate([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)
    truth = get_model(model)(wi, wo, params)
    read = ask(probe, bsdf, [f"f {a:.6f} {x:.9f} {y:.9f} {z:.9f}" for a, (x, y, z) in zip(theta_i, wo)])
    err = np.abs(read / truth - 1)
    print(f"\n{name}: libbsdf at {n} random directions: median |rel. error| {100 * np.median(err):.3g} %, "
          f"90th percentile {100 * np.quantile(err, 0.9):.3g} %")
    rows, tis = tis_lines(bsdf)
    reflectance = ask(probe, bsdf, [f"a {a:g}" for a in incidences])
    print("   θi   truth   libbsdf albedo (vs truth, vs the row's TIS)")
    for a, r in zip(incidences, reflectance):
        true = float(albedo(get_model(model), params, a))
        row = np.flatnonzero(np.isclose(rows, a))
        vs_tis = f"{100 * (r / tis[row[0]] - 1):+6.2f} %" if row.size else "   (between rows)"
        print(f"  {a:4.1f}° {true:.4f}  {r:.4f} ({100 * (r / true - 1):+6.2f} %, {vs_tis})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--libbsdf", type=Path, required=True, help="a libbsdf source checkout (built in SRC/build)")
    args = parser.parse_args()
    print(machine())
    probe = build_probe(args.libbsdf.resolve())
    commit = subprocess.run(["git", "-C", str(args.libbsdf), "rev-parse", "HEAD"], capture_output=True,
                            text=True).stdout.strip() or "(not a git checkout)"
    print(f"settings: libbsdf {commit}; 3000 directions seeded 37; simulated rig seed 1")
    with tempfile.TemporaryDirectory() as tmp:
        tmp_path = Path(tmp)
        for k, path in enumerate(CAMPAIGNS):
            ds = tmp_path / path.stem
            assert rig(["run", str(path), "--out", str(ds), "--quiet"]) == 0
            if k == 0:
                (tmp_path / "fit.json").write_text(json.dumps(FIT))
                out = tmp_path / "fit.bsdf"
                assert rig(["export", str(ds), "--format", "zemax", "--source", "model", "--fit",
                            str(tmp_path / "fit.json"), "--out", str(out)]) == 0
                compare("MRM + Lambert fit (--source model)", probe, out, FIT["model"], FIT["params"],
                        [10.0, 30.5, 60.0, 75.5, 85.0])
            out = tmp_path / f"{path.stem}.bsdf"
            assert rig(["export", str(ds), "--format", "zemax", "--out", str(out)]) == 0
            spec = load_campaign(path).sample.simulated_brdf
            assert spec is not None
            compare(f"{path.stem} (--source data)", probe, out, spec.model, dict(spec.params), PAPER_INCIDENCES)


if __name__ == "__main__":
    main()
