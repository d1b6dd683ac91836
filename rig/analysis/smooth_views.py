"""The measurements as `rig export --format zemax --source data` tabulates them: `rig predict`'s reconstruction with a
smooth (C¹) interpolant within each measured incidence (docs/zemax.md, "The albedo from data").

Why not the piecewise-linear one of `rig predict` (rig.analysis.incidence_views): a tabular BSDF is integrated (its
TIS, a reader's albedo, a ray tracer's energy), and a piecewise-linear interpolant of ln f between views 16–18°
apart cuts a chord under the convex tail of every lobe, where it meets the diffuse floor. On the paper campaign
(Table 2's rings) that overstates the albedo by 0.8–1.0 % at θi 80–85° even from exact values at the views
(benchmarks/zemax_albedo.py). The ln f of a lobe is nearly quadratic in the angle from its axis (Phong's n ln cos,
a Gaussian's square), which a cubic follows and a chord does not: the Clough–Tocher interpolant (a C¹ piecewise
cubic over a triangulation of the same views, its gradients estimated from the views alone; scipy's
CloughTocher2DInterpolator) brings that to +0.03 % and −0.08 %. It consults nothing but the measured values, as
the linear one does.

The disk it interpolates in is the equal-area one (radius ∝ sin(θo/2)) rather than the projected (Nusselt) disk of
`rig predict`: near grazing views the Nusselt disk squeezes θo (sin θo flattens), so the grazing lobes become thin
ridges there whose curvature the cubic's estimated gradients follow less well (+0.30 % rather than +0.03 % at θi 80°
from the exact values). Everything else is `rig predict`'s: the triangulation's views (mirrored across the plane of
incidence), the hull and what counts as extrapolated, the value held beyond the hull (the nearest point of its
edge), the lobe-aligned interpolation between incidences (linear in θi) and its calibration on held-out incidences
(rig.analysis.held_out). The table holds values only, so `DataPredictor` computes no uncertainty: that is four
fifths of `rig predict`'s cost (the linear interpolant's triangles, and a third incidence's bend in θi), and the
export runs over about 90 rows × 20 000 directions.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CloughTocher2DInterpolator
from scipy.spatial import Delaunay

from rig.analysis.held_out import calibrate
from rig.analysis.incidence_views import IncidenceViews
from rig.analysis.predict import MeasuredDomain, lobe_aligned, measured_domain
from rig.data.dataset_reader import Dataset
from rig.data.zemax import TableValues
from rig.physics.geometry import disk_coordinates


def equal_area(xy: np.ndarray) -> np.ndarray:
    """Projected-disk points (M, 2) (radius sin θo) moved to the equal-area disk (radius sin(θo/2) / sin 45°, the
    same azimuth; the rim stays the rim)."""
    r = np.hypot(xy[:, 0], xy[:, 1])
    scale = np.sin(np.arcsin(np.clip(r, 0.0, 1.0)) / 2) / np.sin(np.pi / 4) / np.maximum(r, 1e-12)
    return xy * np.where(r > 1e-12, scale, 0.0)[:, None]


@dataclass
class SmoothIncidenceViews(IncidenceViews):
    """One incidence's views with ln f interpolated by a C¹ cubic inside their hull (module docstring); beyond the
    hull, and the uncertainty everywhere, as `rig predict`'s."""

    @classmethod
    def of(cls, views: IncidenceViews) -> SmoothIncidenceViews:
        return cls(**{f.name: getattr(views, f.name) for f in fields(views)})

    def values(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ln f and inside-ness at disk points (M, 2), without the uncertainty (`evaluate` has it)."""
        inside = self.inside(xy)
        log_f = self._cubic(equal_area(xy))
        if not inside.all():            # held at the nearest point of the hull's edge, as `evaluate` holds it
            edge, t, _ = self._nearest_on_hull(xy[~inside])
            log_f[~inside] = (1 - t) * self.log_f[edge[:, 0]] + t * self.log_f[edge[:, 1]]
        rest = ~np.isfinite(log_f)      # inside the hull's tolerance, outside the cubic's triangles
        if rest.any():
            log_f[rest] = super().evaluate(xy[rest])[0]
        return log_f, inside

    def evaluate(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        linear, u_rel, inside = super().evaluate(xy)
        cubic = self._cubic(equal_area(xy))
        return np.where(inside & np.isfinite(cubic), cubic, linear), u_rel, inside

    @cached_property
    def _cubic(self) -> CloughTocher2DInterpolator:
        return CloughTocher2DInterpolator(with_transforms(Delaunay(equal_area(self.mesh.points))), self.log_f)


def with_transforms(mesh: Delaunay) -> Delaunay:
    """`mesh` with its barycentric transforms (`Delaunay.transform`) computed here, in numpy, before the interpolant
    locates a point: scipy computes them with one LAPACK call per triangle, which OpenBLAS's threads made 6-11 s for
    two incidences on a busy 2-core machine (the reason rig.analysis.incidence_views locates points itself); here
    a millisecond. scipy (1.17) keeps them in `_transform` once computed; should that change, it computes its own
    (slow, the same values). Degenerate triangles get NaN, as scipy gives them."""
    corners = mesh.points[mesh.simplices]
    last = corners[:, 2]
    edges = np.stack([corners[:, 0] - last, corners[:, 1] - last], axis=2)
    det = edges[:, 0, 0] * edges[:, 1, 1] - edges[:, 0, 1] * edges[:, 1, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        inverse = np.stack([np.stack([edges[:, 1, 1], -edges[:, 0, 1]], axis=1),
                            np.stack([-edges[:, 1, 0], edges[:, 0, 0]], axis=1)], axis=1) / det[:, None, None]
    inverse[det == 0] = np.nan
    mesh._transform = np.ascontiguousarray(np.concatenate([inverse, last[:, None, :]], axis=1))
    return mesh


class DataPredictor:
    """The measurements as the export tabulates them (module docstring): values and the `extrapolated` flag of
    `rig predict`'s interpolant (MeasuredDomain.evaluate, less its uncertainty), each incidence's views smooth."""

    def __init__(self, domain: MeasuredDomain, method: str):
        self.domain, self.method = domain, method

    def predict(self, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                phi_o_deg: ArrayLike) -> TableValues:
        ti, pi_, to, po = np.broadcast_arrays(*(np.asarray(a, float) for a in (theta_i_deg, phi_i_deg, theta_o_deg,
                                                                              phi_o_deg)))
        theta_i, xy = ti.ravel(), disk_coordinates(to, po, pi_).reshape(-1, 2)
        lo, hi, w, within = self.domain.brackets(theta_i)
        f_lo, in_lo = self._at_incidence(lo, theta_i, xy)
        f_hi, in_hi = self._at_incidence(hi, theta_i, xy)
        inside = within & (in_lo | (w == 1)) & (in_hi | (w == 0))
        return TableValues(np.exp((1 - w) * f_lo + w * f_hi).reshape(ti.shape), ~inside.reshape(ti.shape))

    def _at_incidence(self, k: np.ndarray, theta_i_deg: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        log_f, inside = np.zeros(len(k)), np.zeros(len(k), bool)
        for j in np.unique(k):
            rows = k == j
            inc = self.domain.incidences[int(j)]
            assert isinstance(inc, SmoothIncidenceViews)
            at = lobe_aligned(xy[rows], theta_i_deg[rows], inc.theta_i_deg) if self.domain.aligned else xy[rows]
            log_f[rows], inside[rows] = inc.values(at)
        return log_f, inside


def smooth_predictor(ds: Dataset) -> DataPredictor:
    """The reconstruction the Zemax export tabulates from data (module docstring), its alignment chosen on held-out
    incidences as `rig predict` does."""
    domain = MeasuredDomain([SmoothIncidenceViews.of(inc) for inc in measured_domain(ds).incidences])
    checks = calibrate(domain)
    held = (f" (leave-one-incidence-out error in ln f, 95th percentile {checks[domain.aligned].p95:.3g} against "
            f"{checks[not domain.aligned].p95:.3g} at {'fixed' if domain.aligned else 'lobe-aligned'} views)"
            if checks else "")
    return DataPredictor(domain, (
        "interpolate: C1 cubic (Clough-Tocher) in ln f over each incidence's views in the equal-area disk, linear in "
        f"theta_i between them at {'lobe-aligned' if domain.aligned else 'fixed'} views{held}; beyond the views' "
        "hull, the value at the hull's nearest edge"))
