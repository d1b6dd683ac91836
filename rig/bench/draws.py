"""Simulated samples nobody tuned for: families, and parameters drawn per seed over the published fits' ranges.

The method studies (`rig bench sampling`, benchmarks/predict_coverage.py) score a method on samples drawn here
rather than on a fixed handful, so that a method cannot be tuned to its test samples. Five families, each with
its parameter ranges from the seed papers (docs/predict.md): RetroPhong around Spieringhs et al. 2023's Table 7
(RM1–RM3), MRM + diffuse around the CEA yellow tape's GGX fit, modified Phong over glossy paints, Oren–Nayar and
Lambertian diffusers. Draw k of a study uses family k mod 5 and its own generator, seeded by (seed, k): one draw
is the same whichever others are drawn with it (a failed draw can be rerun alone, by its seed and index).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FAMILIES = ("retrophong", "mrm_diffuse", "modified_phong", "oren_nayar", "lambert")


def log_uniform(rng: np.random.Generator, lo: float, hi: float) -> float:
    return float(np.exp(rng.uniform(np.log(lo), np.log(hi))))


def draw_params(family: str, rng: np.random.Generator) -> dict[str, float]:
    """Parameters of one sample of the family, over the ranges of the published fits."""
    if family == "retrophong":       # Spieringhs et al. 2023, Table 7 (RM1–RM3) and around
        return {"kd": rng.uniform(0.5, 0.75), "n": log_uniform(rng, 15, 70), "k1": rng.uniform(0.05, 0.2),
                "k2": log_uniform(rng, 1e-4, 0.08), "k3": log_uniform(rng, 1e-5, 6e-3), "k4": rng.uniform(3, 9)}
    if family == "mrm_diffuse":      # the CEA yellow tape's MRM fit (roughness 0.23, F0 0.19) and around
        return {"kd": rng.uniform(0.1, 0.5), "roughness": rng.uniform(0.15, 0.4), "f0": rng.uniform(0.1, 0.3)}
    if family == "modified_phong":   # glossy paints
        return {"kd": rng.uniform(0.1, 0.5), "ks": rng.uniform(0.1, 0.5), "n": log_uniform(rng, 20, 300)}
    if family == "oren_nayar":
        return {"roughness": rng.uniform(0.0, 0.6), "albedo": rng.uniform(0.3, 0.8)}
    if family == "lambert":
        return {"kd": rng.uniform(0.2, 0.9)}
    raise ValueError(f"unknown family {family!r}; choose from {', '.join(FAMILIES)}")


@dataclass(frozen=True)
class Draw:
    """One drawn sample: its index in the study, the study's seed, its family and parameters."""

    index: int
    seed: int
    family: str
    params: dict[str, float]

    @property
    def name(self) -> str:
        return f"{self.family}#{self.index}"

    def describe(self) -> str:
        return f"draw {self.index} (seed {self.seed}, {self.family}: " + ", ".join(
            f"{k} {v:.3g}" for k, v in self.params.items()) + ")"


def draw(seed: int, index: int, families: tuple[str, ...] = FAMILIES) -> Draw:
    """Draw `index` of the study seeded `seed`: family index mod len(families), parameters from its own generator."""
    family = families[index % len(families)]
    return Draw(index, seed, family, draw_params(family, np.random.default_rng([seed, index])))


def draws(seed: int, n: int, first: int = 0, families: tuple[str, ...] = FAMILIES) -> list[Draw]:
    """Draws first, …, first + n − 1 of the study seeded `seed`."""
    return [draw(seed, k, families) for k in range(first, first + n)]
