"""The measured views of one incidence as an interpolant of ln f in the projected disk, with the error it makes.

The views are triangulated together with their mirror images across the plane of incidence (an isotropic sample's
value at Δφ equals its value at −Δφ), so that the plane is interior to the mesh and the interpolant is symmetric,
hence continuous, across it (`mirrored_views`).

The interpolation error is estimated from held-out data: each measured view is predicted from its neighbours alone
(leave one out), and the error found there is turned into a local curvature of ln f. For a quadratic q with
Hessian H, the linear interpolant over a simplex with vertices v_j and barycentric weights w_j errs at x by
exactly ½ Σ w_j (v_j − x)ᵀ H (v_j − x) (the standard error formula of linear interpolation; e.g. Waldron 1998,
"The error in linear interpolation at the vertices of a simplex"). Taking H ≈ κ·I gives
e(x) = ½ κ Σ w_j |v_j − x|²: zero at the measured views, largest in the middle of long edges, and the same
formula at a held-out view gives κ from its leave-one-out error. Beyond the hull the value is held at the nearest
point of the hull's edge; its error there grows with the distance d by the slope of ln f along the way in
(|∇ ln f|·d) and the curvature (½ κ d²).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import Delaunay, cKDTree

#: ...and a view this far (in the projected disk) outside an incidence's hull still counts as inside.
HULL_TOLERANCE = 1e-3
#: Triangles (nearest by centroid) tried first when locating a point in a mesh.
NEAR_TRIANGLES = 12
#: A folded view this close to the plane of incidence (in the projected disk) lies on it: it is not mirrored.
ON_PLANE = 1e-9
#: Views this close to the plane of incidence (≈ 0.1° of azimuth at θo 35°: the plane's nominal views, scattered by
#: the achieved angles) are its views for the curvature along it (`along_plane_curvature`).
PLANE_BAND = 1e-3
#: Views of one incidence closer than this in the projected disk (≈ 0.02° near the normal) are one view measured
#: again: the same nominal direction in several series, scattered by the achieved angles (~0.01°).
SAME_VIEW = 3e-4


def incidence_views(theta_i_deg: float, xy: np.ndarray, log_f: np.ndarray, u_rel: np.ndarray,
                    cache: dict[bytes, np.ndarray] | None = None) -> IncidenceViews | None:
    """The interpolant of one incidence's measured views (disk points (M, 2), ln f, relative u), or None where they
    do not span an area (fewer than three distinct views, or all on one line). `cache`: curvatures by content, kept
    by a caller that rebuilds the domain as rows arrive (adaptive sampling adds one incidence at a time)."""
    xy, log_f, u_rel = repeats_merged(xy, log_f, u_rel)
    if len(xy) < 3:
        return None
    views, source, mirror = mirrored_views(xy)
    try:
        mesh = Delaunay(views)
    except Exception:          # collinear views (a single plane of incidence): no 2-D interpolant
        return None
    key = views.tobytes() + log_f.tobytes()
    kappa = cache.get(key) if cache is not None else None
    if kappa is None:
        kappa = loo_curvature(mesh, log_f[source], u_rel[source], mirror)
        if cache is not None:
            cache[key] = kappa
    return IncidenceViews(theta_i_deg, mesh, log_f[source], u_rel[source], kappa)


def repeats_merged(xy: np.ndarray, log_f: np.ndarray, u_rel: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Views closer than SAME_VIEW (chained) merged into one: their mean position and ln f, and a relative u of
    their RMS u ⊕ the scatter of their ln f (repeats that disagree beyond their u say so). Left apart, two
    repeats 1e-4 apart would bound slivers, and their noise would read as a curvature of 1e4."""
    pairs = cKDTree(xy).query_pairs(SAME_VIEW, output_type="ndarray")
    n = len(xy)
    if not len(pairs):
        return xy, log_f, u_rel
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    size = np.bincount(label, minlength=count)

    def mean(values: np.ndarray) -> np.ndarray:
        return np.bincount(label, values, minlength=count) / size

    mean_log_f = mean(log_f)
    scatter2 = mean((log_f - mean_log_f[label]) ** 2)
    merged_xy = np.column_stack([mean(xy[:, 0]), mean(xy[:, 1])])
    return merged_xy, mean_log_f, np.sqrt(mean(u_rel ** 2) + scatter2)


def mirrored_views(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The folded views (M, 2) and their mirror images (x, −y) across the plane of incidence: the views (K, 2), the
    row of `xy` each comes from (K,), and the index of each view's image (K,; its own index for views on the
    plane, which are not doubled).

    Triangulating the folded half-disk alone makes the plane of incidence (Δφ = 0 and 180°) an edge of the hull:
    the views nearest to it bound thin triangles whose values jump across y = 0, and a view on the plane between
    two measured ones can fall outside the hull altogether."""
    on_plane = np.abs(xy[:, 1]) <= ON_PLANE
    off = np.flatnonzero(~on_plane)
    views = np.concatenate([np.column_stack([xy[:, 0], np.where(on_plane, 0.0, xy[:, 1])]),
                            np.column_stack([xy[off, 0], -xy[off, 1]])])
    source = np.concatenate([np.arange(len(xy)), off])
    mirror = np.arange(len(views))
    mirror[off] = len(xy) + np.arange(len(off))
    mirror[len(xy):] = off
    return views, source, mirror


def loo_curvature(mesh: Delaunay, log_f: np.ndarray, u_rel: np.ndarray, mirror: np.ndarray) -> np.ndarray:
    """κ at each view (module docstring): 2·e / Σ w_j |r_j − v|², where e is the error of the linear interpolant
    of the view's neighbours r_j alone (removing a view changes the triangulation only inside its star) beyond
    what the measurements' own noise explains: e² = max(|ln f̂ − ln f|² − u² − Σ w_j² u_j², 0) with u the relative
    u of the view and of its neighbours (otherwise two close views would turn their noise into a curvature). A
    view and its mirror image are one measurement: both leave together, so that a view near the plane is not
    "predicted" from its own reflection. Where the neighbours cannot interpolate the view (a view on the hull, or
    collinear neighbours), κ is the largest of its neighbours'."""
    indptr, neighbours = mesh.vertex_neighbor_vertices
    kappa = np.full(len(mesh.points), np.nan)
    rings = []
    for k in range(len(mesh.points)):
        pair = {k, int(mirror[k])}
        ring = np.array(sorted({int(v) for j in pair for v in neighbours[indptr[j]:indptr[j + 1]]} - pair))
        rings.append(ring)
        if len(ring) < 3:
            continue
        try:
            local = Delaunay(mesh.points[ring])
        except Exception:          # collinear neighbours: no interpolation to compare with
            continue
        found = containing_triangle(local.points[local.simplices], mesh.points[k])
        if found is None:          # a view of the hull: the others would extrapolate to it
            continue
        simplex, w = found
        corners = ring[local.simplices[simplex]]
        spread = float(w @ ((mesh.points[corners] - mesh.points[k]) ** 2).sum(axis=1))
        noise2 = u_rel[k] ** 2 + float(w ** 2 @ u_rel[corners] ** 2)
        excess = np.sqrt(max((float(w @ log_f[corners]) - log_f[k]) ** 2 - noise2, 0.0))
        if spread > 0:
            kappa[k] = 2 * excess / spread
    known = np.where(np.isfinite(kappa), kappa, 0.0)
    for j in np.flatnonzero(~np.isfinite(kappa)):
        kappa[j] = float(known[rings[j]].max()) if len(rings[j]) else 0.0
    return np.maximum(kappa, along_plane_curvature(mesh.points, log_f, u_rel))


def along_plane_curvature(points: np.ndarray, log_f: np.ndarray, u_rel: np.ndarray) -> np.ndarray:
    """κ of the views on the plane of incidence from their neighbours *along* it (0 elsewhere): the same estimate in
    one dimension, each view interpolated from the next views on the plane either side. Both lobes peak on the
    plane, where ln f bends most along x; a view's triangles there mostly reach off the plane, across the lobe's
    ridge, and their leave-one-out error misses the bend along it."""
    kappa = np.zeros(len(points))
    on = np.flatnonzero((points[:, 1] >= 0) & (points[:, 1] <= PLANE_BAND))
    on = on[np.argsort(points[on, 0])]
    for a, k, b in zip(on[:-2], on[1:-1], on[2:]):
        xa, xk, xb = points[a, 0], points[k, 0], points[b, 0]
        if not xa < xk < xb:
            continue
        w = (xk - xa) / (xb - xa)
        miss = (1 - w) * log_f[a] + w * log_f[b] - log_f[k]
        excess2 = miss ** 2 - u_rel[k] ** 2 - (1 - w) ** 2 * u_rel[a] ** 2 - w ** 2 * u_rel[b] ** 2
        kappa[k] = 2 * np.sqrt(max(excess2, 0.0)) / ((xk - xa) * (xb - xk))
    images = np.flatnonzero((points[:, 1] < 0) & (points[:, 1] >= -PLANE_BAND))
    if images.size and on.size:          # a view's image below the plane: the view's own κ
        twin = cKDTree(points[on] * [1, -1]).query(points[images])[1]
        kappa[images] = kappa[on[twin]]
    return kappa


def containing_triangle(corners: np.ndarray, point: np.ndarray) -> tuple[int, np.ndarray] | None:
    """The first of the triangles (m, 3, 2) that holds `point` (within 1e-12), with its barycentric weights (3,), or
    None. Written out because a small triangulation's `find_simplex`/`transform` costs scipy ~0.1 s a call (it
    prepares the barycentric transforms through LAPACK), over a thousand times this."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    with np.errstate(divide="ignore", invalid="ignore"):
        w1 = ((point[0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (point[1] - a[:, 1])) / det
        w2 = ((b[:, 0] - a[:, 0]) * (point[1] - a[:, 1]) - (point[0] - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
    weights = np.stack([1 - w1 - w2, w1, w2], axis=1)
    inside = np.flatnonzero(np.all(weights >= -1e-12, axis=1) & (det != 0))
    if not inside.size:
        return None
    return int(inside[0]), weights[inside[0]]


@dataclass
class IncidenceViews:
    """The measured views of one incidence: their (mirrored) triangulation, ln f, relative u and curvature κ."""

    theta_i_deg: float
    mesh: Delaunay
    log_f: np.ndarray
    u_rel: np.ndarray
    curvature: np.ndarray         # per view: κ from its leave-one-out error (loo_curvature)

    def inside(self, xy: np.ndarray) -> np.ndarray:
        """Whether each disk point (M, 2) lies in the hull of the views, or within HULL_TOLERANCE of it."""
        edges, facets = self._hull
        p, q = self.mesh.points[edges[:, 0]], self.mesh.points[edges[:, 1]]
        third = self.mesh.points[self.mesh.simplices[facets]].sum(axis=1) - p - q
        pq = q - p
        side = np.sign(pq[:, 0] * (third - p)[:, 1] - pq[:, 1] * (third - p)[:, 0])      # + where the hull is
        dx, dy = xy[:, None, 0] - p[None, :, 0], xy[:, None, 1] - p[None, :, 1]
        distance = side * (pq[:, 0] * dy - pq[:, 1] * dx) / np.hypot(*pq.T)
        return np.all(distance >= -HULL_TOLERANCE, axis=1)

    def locate(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The triangle that holds each disk point (M, 2) (−1 for none) and the point's barycentric weights in it.

        The triangles near each point (by their centroids) are tried first, every triangle for the rest of the
        points inside the hull. Written
        out rather than scipy's `find_simplex`: that needs the mesh's barycentric transforms, which scipy builds
        with a LAPACK call per triangle, and on a busy 2-core machine OpenBLAS's threads made that 36 s for the
        ten incidences of the paper campaign (0.02 s with one thread)."""
        simplex = np.full(len(xy), -1)
        weights = np.zeros((len(xy), 3))
        if not len(xy):
            return simplex, weights
        corners = self.mesh.points[self.mesh.simplices]
        near = self._centroids.query(xy, min(NEAR_TRIANGLES, len(corners)))[1].reshape(len(xy), -1)
        self._first_holding(xy, corners, near, simplex, weights, np.arange(len(xy)))
        missing = np.flatnonzero(simplex < 0)
        missing = missing[self.inside(xy[missing])]          # outside the hull no triangle holds a point
        for start in range(0, len(missing), 256):
            rows = missing[start:start + 256]
            everything = np.broadcast_to(np.arange(len(corners)), (len(rows), len(corners)))
            self._first_holding(xy[rows], corners, everything, simplex, weights, rows)
        return simplex, weights

    @staticmethod
    def _first_holding(xy: np.ndarray, corners: np.ndarray, candidates: np.ndarray, simplex: np.ndarray,
                       weights: np.ndarray, rows: np.ndarray) -> None:
        """For each point, the first candidate triangle (M, K) that holds it: into simplex[rows], weights[rows]."""
        a, b, c = (corners[candidates, j] for j in range(3))
        det = (b[..., 0] - a[..., 0]) * (c[..., 1] - a[..., 1]) - (c[..., 0] - a[..., 0]) * (b[..., 1] - a[..., 1])
        x, y = xy[:, None, 0] - a[..., 0], xy[:, None, 1] - a[..., 1]
        with np.errstate(divide="ignore", invalid="ignore"):      # a degenerate triangle (det 0) holds nothing
            w1 = (x * (c[..., 1] - a[..., 1]) - (c[..., 0] - a[..., 0]) * y) / det
            w2 = ((b[..., 0] - a[..., 0]) * y - x * (b[..., 1] - a[..., 1])) / det
            w = np.stack([1 - w1 - w2, w1, w2], axis=-1)
            holds = np.all(w >= -1e-12, axis=-1) & (det != 0)
        found = holds.any(axis=1) & (simplex[rows] < 0)
        first = np.argmax(holds, axis=1)
        simplex[rows[found]] = candidates[found, first[found]]
        weights[rows[found]] = w[found, first[found]]

    @cached_property
    def _centroids(self) -> cKDTree:
        return cKDTree(self.mesh.points[self.mesh.simplices].mean(axis=1))

    def evaluate(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ln f, u_rel (measurements ⊕ interpolation ⊕ extrapolation) and inside-ness at disk points (M, 2)."""
        simplex, weights = self.locate(xy)
        held = simplex >= 0
        inside = held | self.inside(xy)
        vertices = self.mesh.simplices[np.where(held, simplex, 0)]
        weights = np.clip(weights, 0.0, 1.0)
        weights[held] /= weights[held].sum(axis=1, keepdims=True)
        at = xy.copy()
        slope = np.zeros(len(xy))
        if not held.all():
            edge, t, facet = self._nearest_on_hull(xy[~held])
            vertices[~held] = np.column_stack([edge, edge[:, 0]])
            weights[~held] = np.column_stack([1 - t, t, np.zeros_like(t)])
            at[~held] = self.mesh.points[edge[:, 0]] * (1 - t)[:, None] + self.mesh.points[edge[:, 1]] * t[:, None]
            slope[~held] = self._gradient_norm(facet)
        log_f = (weights * self.log_f[vertices]).sum(axis=1)
        u_meas = (weights * self.u_rel[vertices]).sum(axis=1)
        kappa = self.curvature[vertices].max(axis=1)
        spread = (weights * ((self.mesh.points[vertices] - at[:, None, :]) ** 2).sum(axis=2)).sum(axis=1)
        beyond = np.hypot(*(xy - at).T)
        u_model = 0.5 * kappa * (spread + beyond ** 2) + slope * beyond
        return log_f, np.hypot(u_meas, u_model), inside

    def _gradient_norm(self, simplices: np.ndarray) -> np.ndarray:
        """|∇ ln f| of the linear interpolant on each of the given triangles."""
        corners = self.mesh.points[self.mesh.simplices[simplices]]           # (M, 3, 2)
        values = self.log_f[self.mesh.simplices[simplices]]                  # (M, 3)
        edges = corners[:, 1:] - corners[:, :1]
        rises = values[:, 1:] - values[:, :1]
        gradient = np.linalg.solve(edges, rises[..., None])[..., 0]
        return np.hypot(*gradient.T)

    def _nearest_on_hull(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """For disk points outside the hull: the hull edge nearest to each (its two vertices, (M, 2)), the
        position t ∈ [0, 1] of the nearest point along it, and the triangle on its inner side. Holding the value
        there extends the interpolant continuously across the hull, as the nearest *vertex* would not: between two
        rim views the hull's chord cuts off a sliver of grazing views, and the nearest vertex may be a view far
        along the rim in a lobe."""
        edges, facets = self._hull
        a, b = self.mesh.points[edges[:, 0]], self.mesh.points[edges[:, 1]]
        ab = b - a
        t = np.clip(np.einsum("mhk,hk->mh", xy[:, None, :] - a[None], ab) / np.einsum("hk,hk->h", ab, ab), 0.0, 1.0)
        d2 = (((a[None] + t[..., None] * ab[None]) - xy[:, None, :]) ** 2).sum(axis=2)
        k = np.argmin(d2, axis=1)
        return edges[k], t[np.arange(len(k)), k], facets[k]

    @cached_property
    def _hull(self) -> tuple[np.ndarray, np.ndarray]:
        """The hull's edges (their two vertices) and the triangle that holds each: a triangle's side opposite its
        vertex j is on the hull where it has no neighbour across it."""
        simplex, j = np.nonzero(self.mesh.neighbors == -1)
        others = (j[:, None] + np.array([1, 2])) % 3
        return self.mesh.simplices[simplex[:, None], others], simplex
