"""BRDF models, vectorised over arrays of directions (each model cites its paper in `citation`).

Every model takes unit vectors in the sample coordinate system (z = normal),
both pointing away from the surface, with shape (..., 3), and returns f_r in sr⁻¹.
A pair with either direction at or below the horizon gives 0, and every value is
finite, including grazing, exact retro- and mirror configurations.

A model is plain data about itself (parameter names, bounds, the parameters a
fitter should move in log space, a typical starting point, what it claims about
reciprocity and energy, a citation) plus a pure `evaluate` function; `MODELS` is
the registry campaign files refer to.

Vectors used by the lobes (Spieringhs et al. 2023 Sec. 2; Belcour et al. 2014 Eq. 3):
- i_s = 2(n·i)n − i, the mirror of i (likewise o' for o);
- h = (i + o)/|i + o|, the half vector: h = n in the mirror configuration;
- b = (i + o')/|i + o'|, the back vector: b = n in the retro configuration o = i.
Because o ↦ o' is a rotation by π about n, swapping i and o maps b to its own
mirror, so any lobe of b·n and i·b is reciprocal.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from rig.physics.geometry import dot, sph_to_vec

Evaluate = Callable[..., np.ndarray]

#: Smallest cosine used as a divisor: keeps grazing values finite, changes nothing above it.
_EPS = 1e-12
#: β of the azimuth warp of `albedo`: node density (1 + β)/(1 − β) times higher in the plane of incidence.
_AZIMUTH_CLUSTERING = 0.95


def mirror_about_normal(w: np.ndarray) -> np.ndarray:
    """Mirror of w about z: i_s = 2(n·i)n − i."""
    return w * np.array([-1.0, -1.0, 1.0])


def cos_theta(w: np.ndarray) -> np.ndarray:
    return w[..., 2]


def half_vector(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """h = (i + o)/|i + o|; the zero vector (not NaN) when o = −i."""
    s = wi + wo
    return s / np.maximum(np.linalg.norm(s, axis=-1, keepdims=True), _EPS)


def back_vector(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """b = (i + o')/|i + o'|, o' = mirror of o (Belcour et al. 2014 Eq. 3)."""
    return half_vector(wi, mirror_about_normal(wo))


def schlick(cos_u: np.ndarray, f0: float) -> np.ndarray:
    """Schlick Fresnel F(u) = F0 + (1 − F0)(1 − u)^5 (Spieringhs et al. 2023 Eq. 7)."""
    return f0 + (1.0 - f0) * (1.0 - np.clip(cos_u, 0.0, 1.0)) ** 5


def phong_lobe(cos_angle: np.ndarray, n: float) -> np.ndarray:
    """Normalised Phong lobe (n+2)/(2π)·max(0, cos)^n: albedo 1 at normal incidence.

    The power is exp(n·ln cos), and exp(−∞) = 0 where cos ≤ 0: within n·|ln cos| ulp of pow's
    (< 10⁻¹³ relative for the lobes fitted), and a third faster than glibc's pow on a simulated
    frame's pixels."""
    norm = (n + 2.0) / (2.0 * np.pi)
    if n == 0:
        return np.full(np.shape(cos_angle), norm)
    c = np.full(np.shape(cos_angle), -np.inf)
    np.log(cos_angle, out=c, where=~np.less_equal(cos_angle, 0.0))   # (libm's log(0) takes a slow error path)
    c *= n
    np.exp(c, out=c)
    c *= norm
    return c


def abc_lobe(cos_angle: np.ndarray, a: float, b: float, c: float) -> np.ndarray:
    """ABC lobe A/(1 + B(1 − cos))^C (Spieringhs et al. 2023 Eq. 10), in log form so it never overflows."""
    return a * np.exp(-c * np.log1p(b * (1.0 - np.clip(cos_angle, 0.0, 1.0))))


def beckmann_ndf(cos_m: np.ndarray, alpha: float) -> np.ndarray:
    """Beckmann D = exp((cos²β − 1)/(α² cos²β)) / (π α² cos⁴β) (Spieringhs et al. 2023 Eq. 6).

    Evaluated as one exponential so that grazing β (cos β → 0) gives 0, not 0/0.
    """
    c = np.clip(cos_m, np.finfo(float).tiny, 1.0)
    with np.errstate(over="ignore", divide="ignore"):
        log_d = -(1.0 - c * c) / (alpha * c) ** 2 - 4.0 * np.log(c) - np.log(np.pi * alpha**2)
    return np.where(cos_m > 0.0, np.exp(log_d), 0.0)


def ggx_ndf(cos_m: np.ndarray, alpha: float) -> np.ndarray:
    """GGX / Trowbridge–Reitz D = α² / (π (cos²θm (α² − 1) + 1)²) (Walter et al. 2007 Eq. 33)."""
    c2 = np.clip(cos_m, 0.0, 1.0) ** 2
    return np.where(cos_m > 0.0, alpha**2 / (np.pi * (c2 * (alpha**2 - 1.0) + 1.0) ** 2), 0.0)


def ggx_visibility(cos_i: np.ndarray, cos_o: np.ndarray, alpha: float) -> np.ndarray:
    """G2/(4 cos θi cos θo) for the height-correlated Smith G2 = 1/(1 + Λ(i) + Λ(o)) of GGX.

    With Λ(c) = (√(α² + c²(1 − α²))/c − 1)/2 (Heitz 2014 Eqs. 72, 99) this is
    1 / (2 (cos θo √(α² + cos²θi (1 − α²)) + cos θi √(α² + cos²θo (1 − α²)))),
    which stays finite at grazing where G2 and the cosines vanish together.
    """
    a2 = alpha**2
    si = np.sqrt(a2 + cos_i**2 * (1.0 - a2))
    so = np.sqrt(a2 + cos_o**2 * (1.0 - a2))
    return 0.5 / np.maximum(cos_o * si + cos_i * so, _EPS)


def cook_torrance_g(cos_i: np.ndarray, cos_o: np.ndarray, cos_h: np.ndarray,
                    cos_ih: np.ndarray) -> np.ndarray:
    """V-cavity G(i, o, h) = min(1, 2(n·h)(n·o)/(o·h), 2(n·h)(n·i)/(o·h)) (Cook & Torrance 1982), o·h = i·h."""
    k = 2.0 * cos_h / np.maximum(cos_ih, _EPS)
    return np.minimum(1.0, k * np.minimum(cos_i, cos_o))


def _hemisphere(evaluate: Evaluate) -> Evaluate:
    """Zero a model where ωi or ωo is at or below the horizon; broadcast to the directions' shape."""
    @functools.wraps(evaluate)
    def wrapped(wi: np.ndarray, wo: np.ndarray, **params: float) -> np.ndarray:
        wi, wo = np.asarray(wi, float), np.asarray(wo, float)
        above = (cos_theta(wi) > 0.0) & (cos_theta(wo) > 0.0)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            return np.where(above, evaluate(wi, wo, **params), 0.0)
    return wrapped


@_hemisphere
def lambert(wi: np.ndarray, wo: np.ndarray, *, kd: float) -> np.ndarray:
    """f = kd/π (kd = albedo)."""
    return np.asarray(kd / np.pi)


@_hemisphere
def modified_phong(wi: np.ndarray, wo: np.ndarray, *, kd: float, ks: float, n: float) -> np.ndarray:
    """Modified Phong (Lafortune), Spieringhs 2023 Eq. 3: kd/π + ks (n+2)/(2π) (i_s·o)^n.

    Reciprocal (i_s·o = i·o_s); albedo ≤ kd + ks, equal at normal incidence (Lewis 1994).
    """
    return kd / np.pi + ks * phong_lobe(dot(mirror_about_normal(wi), wo), n)


@_hemisphere
def retrophong(wi: np.ndarray, wo: np.ndarray, *, kd: float, n: float,
               k1: float, k2: float, k3: float, k4: float) -> np.ndarray:
    """RetroPhong, Spieringhs 2023 Eqs. 15, 17, 18.

    f = kd/π + ks(θi) (n+2)/(2π) (i_s·o)^n + kr(θi) (n+2)/(2π) (i·o)^n with
    kr(θi) = k1 (1 − cos θi) + k2 (retro lobe) and ks(θi) = k3 exp(k4 (1 − cos θi))
    (specular lobe). The paper's appendix code swaps the two names; the equations win.
    The weights depend on θi only, so the model is not reciprocal, and kd + ks + kr
    exceeds 1 beyond θi = 85° for the paper's fits: no energy claim.
    """
    one_minus_cos = 1.0 - cos_theta(wi)
    kr = k1 * one_minus_cos + k2
    ks = k3 * np.exp(k4 * one_minus_cos)
    return (kd / np.pi
            + ks * phong_lobe(dot(mirror_about_normal(wi), wo), n)
            + kr * phong_lobe(dot(wi, wo), n))


@_hemisphere
def oren_nayar(wi: np.ndarray, wo: np.ndarray, *, roughness: float, albedo: float) -> np.ndarray:
    """Qualitative Oren–Nayar model (Oren & Nayar 1994 Eq. 30; Spieringhs 2023 ref. [21]).

    f = ρ/π (A + B max(0, cos(φi − φo)) sin α tan β), α = max(θi, θo), β = min(θi, θo),
    A = 1 − 0.5 σ²/(σ² + 0.33), B = 0.45 σ²/(σ² + 0.09), σ = `roughness` (α_m, radians).
    Since sin θi sin θo cos(φi − φo) = i·o − cos θi cos θo and cos β = max(cos θi, cos θo),
    the angular term is max(0, i·o − cos θi cos θo) / max(cos θi, cos θo): no azimuth,
    so nothing depends on φ at the pole, and it is symmetric in i and o (reciprocal).
    No energy claim: the qualitative model's albedo exceeds ρ near grazing incidence
    for small σ (1.014 at θi = 89°, σ = 0.2, ρ = 1).
    """
    s2 = roughness**2
    a = 1.0 - 0.5 * s2 / (s2 + 0.33)
    b = 0.45 * s2 / (s2 + 0.09)
    ci, co = cos_theta(wi), cos_theta(wo)
    angular = np.maximum(dot(wi, wo) - ci * co, 0.0) / np.maximum(np.maximum(ci, co), _EPS)
    return albedo / np.pi * (a + b * angular)


@_hemisphere
def beckmann_retro(wi: np.ndarray, wo: np.ndarray, *, kd: float, alpha: float, r0: float) -> np.ndarray:
    """Beckmann-Retro, Spieringhs 2023 Eqs. 5–7: kd/π + f_r + f_b.

    Retro lobe f_b = F(o'·b) G(i, o, h) D(b·n) / (4 |i·n| |o·n|) with the back vector b
    (Belcour 2014); forward lobe f_r the same with h in place of b (F(i·h), D(h·n)).
    D is Beckmann, F Schlick, G the Cook–Torrance V-cavity term of the true half vector.
    Table 6/7 lists a single α and R0 per fit, so both lobes share them. Reciprocal
    (o'·b = i·b); no energy claim, the two lobes each carry up to the full albedo.
    """
    ci, co = cos_theta(wi), cos_theta(wo)
    h, b = half_vector(wi, wo), back_vector(wi, wo)
    g_over_cosines = cook_torrance_g(ci, co, cos_theta(h), dot(wi, h)) / (4.0 * np.maximum(ci * co, _EPS))
    forward = schlick(dot(wi, h), r0) * beckmann_ndf(cos_theta(h), alpha)
    retro = schlick(dot(wi, b), r0) * beckmann_ndf(cos_theta(b), alpha)
    return kd / np.pi + (forward + retro) * g_over_cosines


@_hemisphere
def blinn_retro(wi: np.ndarray, wo: np.ndarray, *, kd: float, alpha_b: float, alpha_r: float) -> np.ndarray:
    """Blinn-Retro, Spieringhs 2023 Eqs. 8–9: kd/π + (h·n)^α_r + (b·n)^α_b.

    Subscript b = back vector (retro lobe), r = reflection (forward lobe of the half
    vector h), as f_b is the back-vector lobe of Eq. 5. The lobes are unnormalised,
    with peak 1 sr⁻¹, as in the paper (its Table 7 has no lobe weights) and in
    Belcour's ALTA `retroblinn`. Reciprocal; no energy claim (each lobe's albedo → π as α → 0).
    """
    cos_h, cos_b = cos_theta(half_vector(wi, wo)), cos_theta(back_vector(wi, wo))
    return kd / np.pi + np.maximum(cos_h, 0.0) ** alpha_r + np.maximum(cos_b, 0.0) ** alpha_b


@_hemisphere
def abc_retro(wi: np.ndarray, wo: np.ndarray, *, kd: float, r0: float,
              a_b: float, b_b: float, c_b: float, a_r: float, b_r: float, c_r: float) -> np.ndarray:
    """ABC-Retro, Spieringhs 2023 Eqs. 10–11: kd/π + F(i·h) ABC_r(h·n) + F(o'·b) ABC_b(b·n).

    ABC(cos) = A/(1 + B(1 − cos))^C with Schlick F of the single R0 of Table 7.
    Subscript b = back vector (retro lobe), r = reflection (forward lobe of h), as in
    `blinn_retro`. Reciprocal; no energy claim (A is an unnormalised peak value).
    """
    h, b = half_vector(wi, wo), back_vector(wi, wo)
    forward = schlick(dot(wi, h), r0) * abc_lobe(cos_theta(h), a_r, b_r, c_r)
    retro = schlick(dot(wi, b), r0) * abc_lobe(cos_theta(b), a_b, b_b, c_b)
    return kd / np.pi + forward + retro


@_hemisphere
def ggx(wi: np.ndarray, wo: np.ndarray, *, roughness: float, f0: float) -> np.ndarray:
    """GGX microfacet BRDF f = F(i·h) D(h·n) G2(i, o) / (4 cos θi cos θo) (Walter et al. 2007 Eq. 20).

    D = GGX with α = `roughness`² — `roughness` is the perceptual roughness of OpenPBR and
    MaterialX, the convention of the published MRM fit (Portsmouth 2026: 0.23 for the
    yellow tape) — G2 = height-correlated Smith (Heitz 2014 Eq. 99), F = Schlick with
    normal-incidence reflectance `f0`. Reciprocal; single scattering only, so the albedo
    is < 1 for f0 ≤ 1.
    """
    h = half_vector(wi, wo)
    alpha = roughness ** 2
    return (schlick(dot(wi, h), f0) * ggx_ndf(cos_theta(h), alpha)
            * ggx_visibility(cos_theta(wi), cos_theta(wo), alpha))


@_hemisphere
def mrm(wi: np.ndarray, wo: np.ndarray, *, roughness: float, f0: float) -> np.ndarray:
    """Minimal Retroreflective Microfacet model (Portsmouth et al. 2026): f_MRM(o, i) = f_GGX(o', i).

    Mirroring o about n sends the half vector to the back vector b, so D is evaluated
    at b·n, F at i·b, and G2 is unchanged (o'·n = o·n). o ↦ o' preserves solid angle
    and cos θo, so the albedo equals GGX's; reciprocal for the reflection-symmetric GGX NDF.
    """
    return ggx(wi, mirror_about_normal(wo), roughness=roughness, f0=f0)


@_hemisphere
def mrm_diffuse(wi: np.ndarray, wo: np.ndarray, *, kd: float, roughness: float, f0: float) -> np.ndarray:
    """kd/π + MRM: a Lambertian base under the retroreflective lobe.

    The albedo is kd + the GGX albedo, which is not bounded by 1 for kd ≤ 1: no energy claim.
    """
    return kd / np.pi + mrm(wi, wo, roughness=roughness, f0=f0)


@dataclass(frozen=True, kw_only=True)
class BrdfModel:
    """A model and what a fitter or a campaign needs to know about it.

    bounds: closed range of every parameter, in `evaluate`'s order; log_scale: the
    parameters to fit in log space (exponents, tiny coefficients; their lower bound is
    > 0); typical: a starting point inside the bounds; reciprocal / energy_conserving:
    what the model claims (f(i, o) = f(o, i); directional albedo ≤ 1 at every
    incidence, for modified Phong when kd + ks ≤ 1).
    """

    name: str
    evaluate: Evaluate
    bounds: Mapping[str, tuple[float, float]]
    log_scale: frozenset[str]
    typical: Mapping[str, float]
    reciprocal: bool
    energy_conserving: bool
    citation: str

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(self.bounds)

    def __call__(self, wi: np.ndarray, wo: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        return self.evaluate(wi, wo, **params)


def albedo(model: BrdfModel, params: Mapping[str, float], theta_i_deg: np.ndarray | float,
           n: int = 128) -> np.ndarray:
    """Directional albedo ∫ f(i, o) cos θo dωo over the viewing hemisphere, per θi (degrees).

    n-point Gauss–Legendre in cos θo times a 2n-point midpoint rule in u, with the azimuth
    φo = u − (β/2) sin 2u (β = 0.95): periodic, so still spectrally accurate, with nodes
    20× denser in the plane of incidence, where the lobes peak and, at grazing incidence,
    are narrowest in φ. The incidence lies in the plane φi = 0; the result has θi's shape.
    With n = 128: ~1e-5 for GGX α ≥ 0.1 and Phong 1 ≤ n ≤ 3000 at any θi ≤ 89°, ~1e-3
    for lobes with a kink at the horizon (Phong n < 1) near grazing.
    """
    x, w = np.polynomial.legendre.leggauss(n)
    mu, w_mu = 0.5 * (x + 1.0), 0.5 * w
    u = (np.arange(2 * n) + 0.5) * (np.pi / n)
    phi = u - 0.5 * _AZIMUTH_CLUSTERING * np.sin(2.0 * u)
    w_phi = (1.0 - _AZIMUTH_CLUSTERING * np.cos(2.0 * u)) * (np.pi / n)
    wo = sph_to_vec(np.arccos(mu)[:, None], phi[None, :])
    theta_i = np.radians(np.asarray(theta_i_deg, float))
    wi = sph_to_vec(theta_i, np.zeros_like(theta_i))[..., None, None, :]
    f = model(wi, wo, params)
    return np.sum(f * (mu * w_mu)[:, None] * w_phi, axis=(-2, -1))


#: Bounds are physical ranges (docs/fit.md). Albedo kd, Schlick f0 / R0: fractions of the incident light.
_UNIT = (0.0, 1.0)
#: Lobe exponents: cos^n is √(2 ln 2 / n) rad wide at half maximum, 0.21° at 1e5 (Table 7's narrowest: 1.65e4,
#: 0.5°; Table 2's nearest views: 3.3°); at 0.1 it is flat within 20 % over the hemisphere, a diffuse term.
_EXPONENT = (0.1, 1e5)
#: Perceptual GGX roughness: α = roughness² from 1e-3 (a lobe of 0.06°, a mirror) to 1 (D uniform in h).
_ROUGHNESS = (0.03, 1.0)

MODELS: dict[str, BrdfModel] = {
    m.name: m for m in (
        BrdfModel(name="lambert", evaluate=lambert, bounds={"kd": _UNIT}, log_scale=frozenset(),
                  typical={"kd": 0.5}, reciprocal=True, energy_conserving=True, citation="Lambert"),
        BrdfModel(name="modified_phong", evaluate=modified_phong,
                  bounds={"kd": _UNIT, "ks": _UNIT, "n": _EXPONENT}, log_scale=frozenset({"n"}),
                  typical={"kd": 0.620, "ks": 0.132, "n": 24.0},      # RM1 first fit at θi = 80°
                  reciprocal=True, energy_conserving=True,
                  citation="Lafortune 1994; Spieringhs et al. 2023 Eq. 3"),
        BrdfModel(name="retrophong", evaluate=retrophong,
                  # k1–k3: at 10 one lobe returns ten times the light falling on the sample; k2, k3 down to
                  # 1e-15, below any noise (RM3's k2: 1.53e-12); k4 ≤ 50: ks × e^50 at grazing (Table 7: 3.4–8.7)
                  bounds={"kd": _UNIT, "n": _EXPONENT, "k1": (0.0, 10.0), "k2": (1e-15, 10.0),
                          "k3": (1e-15, 10.0), "k4": (0.0, 50.0)},
                  log_scale=frozenset({"n", "k2", "k3"}),
                  typical={"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47},
                  reciprocal=False, energy_conserving=False,
                  citation="Spieringhs et al. 2023 Eqs. 15, 17, 18; Table 3 (RM1)"),
        BrdfModel(name="oren_nayar", evaluate=oren_nayar,
                  # σ, the facets' slope angle spread in radians: 0 (a flat Lambertian) to π/2 (vertical)
                  bounds={"roughness": (0.0, np.pi / 2), "albedo": _UNIT}, log_scale=frozenset(),
                  typical={"roughness": 0.865, "albedo": 0.268},
                  reciprocal=True, energy_conserving=False,
                  citation="Oren & Nayar 1994 Eq. 30; Spieringhs et al. 2023 Table 6 (RM1)"),
        BrdfModel(name="beckmann_retro", evaluate=beckmann_retro,
                  # α, the RMS facet slope: 1e-3 a lobe of 0.06°; at 1e5 D is flat and 1e-10 sr⁻¹, no lobe
                  bounds={"kd": _UNIT, "alpha": (1e-3, 1e5), "r0": _UNIT}, log_scale=frozenset({"alpha"}),
                  typical={"kd": 0.796, "alpha": 8.20, "r0": 0.995},
                  reciprocal=True, energy_conserving=False,
                  citation="Spieringhs et al. 2023 Eqs. 5-7, Table 7 (RM1); Belcour et al. 2014 Eq. 3"),
        BrdfModel(name="blinn_retro", evaluate=blinn_retro,
                  bounds={"kd": _UNIT, "alpha_b": _EXPONENT, "alpha_r": _EXPONENT},
                  log_scale=frozenset({"alpha_b", "alpha_r"}),
                  typical={"kd": 0.919, "alpha_b": 2.77e3, "alpha_r": 7.91e3},
                  reciprocal=True, energy_conserving=False,
                  citation="Spieringhs et al. 2023 Eqs. 8-9, Table 7 (RM1); Belcour et al. 2014 Eq. 3"),
        BrdfModel(name="abc_retro", evaluate=abc_retro,
                  # A: peak, sr⁻¹ (tapes: ~1e2); B: inverse width (1e4: half maximum at 0.8° for C = 1); C → ∞ at
                  # fixed B·C is the Gaussian exp(−BC(1 − cos)), within a few % at C = 100: at C's bound, that limit
                  bounds={"kd": _UNIT, "r0": _UNIT,
                          "a_b": (1e-6, 1e3), "b_b": (1e-6, 1e4), "c_b": (1e-4, 100.0),
                          "a_r": (1e-6, 1e3), "b_r": (1e-6, 1e4), "c_r": (1e-4, 100.0)},
                  log_scale=frozenset({"a_b", "b_b", "c_b", "a_r", "b_r", "c_r"}),
                  typical={"kd": 0.534, "r0": 0.0472, "a_b": 1.82, "b_b": 13.5, "c_b": 1.51,
                           "a_r": 1.02, "b_r": 0.0775, "c_r": 6.97},
                  reciprocal=True, energy_conserving=False,
                  citation="Spieringhs et al. 2023 Eqs. 10-11, Table 7 (RM1); Belcour et al. 2014 Eq. 3"),
        BrdfModel(name="ggx", evaluate=ggx,
                  bounds={"roughness": _ROUGHNESS, "f0": _UNIT}, log_scale=frozenset({"roughness"}),
                  typical={"roughness": 0.23, "f0": 0.19},
                  reciprocal=True, energy_conserving=True,
                  citation="Walter et al. 2007; Heitz 2014 (height-correlated Smith); Schlick 1994"),
        BrdfModel(name="mrm", evaluate=mrm,
                  bounds={"roughness": _ROUGHNESS, "f0": _UNIT}, log_scale=frozenset({"roughness"}),
                  typical={"roughness": 0.23, "f0": 0.19},
                  reciprocal=True, energy_conserving=True,
                  citation="Portsmouth, Raab, Belcour, Liu 2026 (JCGT 15(1)); GGX as in `ggx`"),
        BrdfModel(name="mrm_diffuse", evaluate=mrm_diffuse,
                  bounds={"kd": _UNIT, "roughness": _ROUGHNESS, "f0": _UNIT},
                  log_scale=frozenset({"roughness"}),
                  typical={"kd": 0.3, "roughness": 0.23, "f0": 0.19},
                  reciprocal=True, energy_conserving=False,
                  citation="Lambert + Portsmouth et al. 2026"),
    )
}


def get_model(name: str) -> BrdfModel:
    try:
        return MODELS[name]
    except KeyError:
        raise KeyError(f"unknown BRDF model {name!r}; known: {', '.join(sorted(MODELS))}") from None
