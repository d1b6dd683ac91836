"""The sample's static grain in the ROI texture: how much of it there is, and how much every point shares (issue 34).

The ROI's texture u (rig.physics.roi: the spread of its block means about their plane) holds two things. Glints
(beads, aggregate facets) light up for some directions and not others: they change from view to view and are a
point's own error. The static grain (the reflectance pattern of the sample's surface) is the same in every view of
the same area, and the ROI looks at the sample's centre from every view: two views' ROI means share its error as
far as their footprints overlap, so most of it is one offset of the whole campaign, not a scatter between points.

Its share is estimated from the data: each point keeps its ROI block pattern (`roi_pattern`: block means about
their plane over their mean). Two views whose block grids fall on the same sample area (no ROI corner more than
SAME_AREA_BLOCKS apart: `grid_map`, from the axes' positions) but whose half vectors are more than GLINT_APART_DEG
apart (their glints differ) share exactly the static part of their patterns, so over such pairs
Σ pᵢ·pⱼ / Σ ½(|pᵢ|² + |pⱼ|²) estimates the static share of the block variance (`StaticTexture.share`). Of a
point's static error sᵢ, what the campaign's mean static error s̄ (one shift of every point) takes with it is
σᵢ² − Var(sᵢ − s̄), from the overlaps of the views' footprints on the sample (`StaticTexture.common_variance`).

On the simulated rig (docs/uncertainty.md) the pair estimate gives 0.20–0.27 where the static factor, rendered
apart, makes 0.23–0.28 of the block patterns' power, and the footprint overlap predicts the correlation of two
views' static errors (0.30, 0.46, 0.72, 0.92 measured over 30 seeds for 0.3, 0.5, 0.7, 0.9 predicted).

Glints are not every view's own, though: views whose half vectors lie within a degree or two see the same ones.
The same-area pairs closer than GLINT_APART_DEG, binned by the half vectors' distance (GLINT_BINS_DEG), give
what such views share beyond the static grain (`StaticTexture.glint_excess`); a view's covariance with the
campaign's mean then takes that share of its whole texture variance over the views of each bin, as far as their
footprints overlap. On the issue's glossy sample (modified Phong n = 3000, its lobe's views all within a degree
of the normal's half vector) the pairs closer than 0.5° share 0.88 of their patterns, 0.5–1° 0.74, 1–2° 0.44,
beyond 2° the static share (0.15).

The glints' part of that common variance may be negative. On a glossy sample most views are the lobe's, and the
glints they share make most of the campaign's mean error; a view off the lobe shares none of them, so it varies
about that mean by more than its own texture: Var(tᵢ − t̄) = σᵢ² − 2 Cov(tᵢ, t̄) + Var(t̄) > σᵢ², and its
point-to-point u takes the difference (such views of the glossy sample read z std 1.20 without it, 0.97 with it).
Its total u then exceeds its own texture's by that much: the split is in one shift of the whole campaign, and a
view that does not share it is farther from it. The static grain's part stays at least 0: signed, the paper table's
views along the normal (small footprints, little overlap) came out over-covered (z std 0.79–0.84 against
0.87–0.94), i.e. the overlap model is not that accurate where views share little.
"""

from __future__ import annotations

import numpy as np

from rig.physics.block_correlation import BlockCorrelation
from rig.physics.geometry import camera_frame, sample_frame, sph_to_vec

#: Two views' block grids fall on the same sample area when no ROI corner lies farther apart than this (blocks).
SAME_AREA_BLOCKS = 0.3
#: Two views' glints are unrelated when their half vectors are farther apart than this (degrees): the simulated
#: sample's glints decorrelate within 4° of the half vector; a real one's is not known, so the margin is wide.
GLINT_APART_DEG = 5.0
#: Half-vector distances (deg) binning the same-area pairs that may share glints (up to GLINT_APART_DEG): what
#: two views that close share beyond the static grain (`StaticTexture.glint_excess`).
GLINT_BINS_DEG = (0.5, 1.0, 2.0, 3.5, GLINT_APART_DEG)
#: Pairs of such views needed before the share is estimated; with fewer it is 0 (the texture stays point-to-point).
MIN_PAIRS = 20
#: Points per side of the grid that measures the overlap of two footprints.
OVERLAP_GRID = 16
#: A view whose footprint is longer than this many times the normal view's (θo beyond about 87°) sees the sample
#: nearly edge-on: its block grid is not compared, and its static grain stays its own.
MAX_STRETCH = 20.0
#: Views a footprint's mean overlap is taken over at most (evenly spread over those seen): a mean, not a sum.
MAX_VIEWS = 400


def usable(grid: np.ndarray) -> bool:
    """Whether a `grid_map` is a footprint on the sample: finite, not edge-on (MAX_STRETCH)."""
    return bool(np.all(np.isfinite(grid)) and 0 < abs(np.linalg.det(grid)) <= MAX_STRETCH)


def grid_map(motors_deg: tuple[float, float, float, float]) -> np.ndarray:
    """The ROI's block grid on the sample: the 2 × 2 map from an offset (columns, rows) in the image to sample
    (x, y), in units of the grid's size when the camera looks along the normal. The image offset moves the ray
    by sensor x and −sensor y (rig.physics.optics.ray_directions); it meets the sample plane along the view
    axis; the camera's distance and focal length only scale it, alike for every view."""
    alpha, beta, a, b = np.radians(np.asarray(motors_deg, float))
    frame, camera = sample_frame(alpha, beta), camera_frame(a, b)
    normal, axis = frame[:, 2], camera[:, 2]
    image_axes = np.stack([camera[:, 0], -camera[:, 1]], axis=1)              # GCS, (3, 2)
    on_plane = image_axes - np.outer(axis, normal @ image_axes) / (axis @ normal)
    return frame[:, :2].T @ on_plane


def half_vector(theta_i_deg: float, phi_i_deg: float, theta_o_deg: float, phi_o_deg: float) -> np.ndarray:
    """Unit half vector of a view (SCS)."""
    h = sph_to_vec(np.radians([theta_i_deg, theta_o_deg]), np.radians([phi_i_deg, phi_o_deg])).sum(axis=0)
    return h / np.linalg.norm(h)


class StaticTexture:
    """The run's estimate, from the points seen so far (`observe`); one per run (rig.acquisition.rows).

    Each point's pattern is compared with every earlier one's once, and its footprint's overlap with theirs is
    taken once: about 1.5 ms per point over a 2000-point campaign."""

    def __init__(self) -> None:
        self._patterns = np.empty((0, 0))
        self._inverse = np.empty((0, 2, 2))          # each view's sample → block grid map
        self._areas = np.empty(0)                    # |det| of its grid map: its footprint's area
        self._halves = np.empty((0, 3))
        self._maps = np.empty((0, 2, 2))
        self._seen: set[str] = set()
        self._common: dict[str, float] = {}
        self._shape: tuple[int, int] | None = None
        self._cross = np.zeros(len(GLINT_BINS_DEG) + 1)    # per half-vector bin; the last: glints apart
        self._power = np.zeros(len(GLINT_BINS_DEG) + 1)
        self._pairs = np.zeros(len(GLINT_BINS_DEG) + 1, int)
        self._shared: dict[str, float] = {}
        self._block_area = 0.0                       # Σ block variance (relative) × footprint area
        self.n = 0
        #: How the ROI's block means correlate, pooled over the run's views: the texture u a point's block
        #: variance is (rig.physics.block_correlation); the run's other texture state, kept with this one.
        self.blocks = BlockCorrelation()

    def observe(self, point_id: str, pattern: np.ndarray, grid: np.ndarray, half: np.ndarray,
                block_rel_sq: float) -> None:
        """Add a point's ROI pattern (rows × columns of blocks), its `grid_map`, `half_vector` and the relative
        variance of its ROI mean from the block spread (noise and texture). A point seen
        before (its row is built again once E⊥ brackets it) is not added twice; patterns of another grid than the
        first, and edge-on views (`usable`), are left out."""
        if point_id in self._seen or (self._shape is not None and pattern.shape != self._shape) or not usable(grid):
            return
        self._seen.add(point_id)
        if self._shape is None:
            self._shape = (int(pattern.shape[0]), int(pattern.shape[1]))
            self._patterns = np.empty((0, pattern.size))
        p, n = pattern.ravel().astype(float), self.n
        if n:
            d = self._maps[:n] - grid                                       # corner (±cols/2, ±rows/2) moves by d·c
            rows, cols = self._shape
            dx, dy = d[:, :, 0] * cols / 2.0, d[:, :, 1] * rows / 2.0
            apart = np.sqrt(np.maximum(np.sum((dx + dy) ** 2, axis=1), np.sum((dx - dy) ** 2, axis=1)))
            glints = np.degrees(np.arccos(np.clip(self._halves[:n] @ half, -1.0, 1.0)))
            same = apart < SAME_AREA_BLOCKS
            k = np.searchsorted(GLINT_BINS_DEG, glints[same])
            others = self._patterns[:n][same]
            np.add.at(self._cross, k, others @ p)
            np.add.at(self._power, k, 0.5 * (np.sum(others ** 2, axis=1) + p @ p))
            np.add.at(self._pairs, k, 1)
        if n == len(self._areas):                    # room for twice as many
            grow = max(2 * n, 64)
            self._patterns = _resized(self._patterns, grow)
            self._inverse, self._maps = _resized(self._inverse, grow), _resized(self._maps, grow)
            self._areas, self._halves = _resized(self._areas, grow), _resized(self._halves, grow)
        self._patterns[n], self._maps[n], self._inverse[n] = p, grid, np.linalg.inv(grid)
        self._areas[n], self._halves[n] = abs(np.linalg.det(grid)), half
        self._block_area += block_rel_sq * self._areas[n]
        self.n += 1

    @property
    def pairs(self) -> int:
        """Pairs of views on the same area whose glints differ: what the static share is estimated from."""
        return int(self._pairs[-1])

    @property
    def share(self) -> float:
        """The static grain's share of the ROI block variance, 0 until MIN_PAIRS pairs of views gave it."""
        if self.pairs < MIN_PAIRS or self._power[-1] <= 0:
            return 0.0
        return float(np.clip(self._cross[-1] / self._power[-1], 0.0, 1.0))

    def glint_excess(self) -> np.ndarray:
        """Per bin of half-vector distance (GLINT_BINS_DEG): the share of the block variance two views on the same
        area share beyond the static grain (their glints), 0 for a bin with fewer than MIN_PAIRS pairs."""
        enough = (self._pairs[:-1] >= MIN_PAIRS) & (self._power[:-1] > 0)
        ratio = np.divide(self._cross[:-1], self._power[:-1], out=np.zeros(len(GLINT_BINS_DEG)), where=enough)
        return np.where(enough, np.clip(ratio - self.share, 0.0, 1.0), 0.0)

    def common_variance(self, point_id: str, grid: np.ndarray, half: np.ndarray | None = None,
                        own_rel_sq: float = 0.0) -> float:
        """The relative variance of a view's texture error that the campaign's mean texture error takes with it:
        σᵢ² − Var(tᵢ − t̄) = 2 Cov(tᵢ, t̄) − Var(t̄) (module docstring), over the views seen so far. The static
        grain's part is at least 0; the glints' may be negative (module docstring: a flat view of a glossy sample).

        The static grain: a grain much finer than the footprint gives a view's ROI mean a static variance
        σᵢ² = S/Aᵢ (Aᵢ its footprint's area; S = share × the mean of block variance × area) and two views a
        covariance S |Aᵢ ∩ Aⱼ| / (Aᵢ Aⱼ), so Cov(sᵢ, s̄) = σᵢ² · mean over j of |Aᵢ ∩ Aⱼ| / Aⱼ. A small footprint
        (a view along the normal) has the largest static error and shares the least of it; a long one (a grazing
        view) holds the others and shares nearly all of its small one.

        The glints: views whose half vectors lie within a few degrees see the same glints, as far as their
        footprints overlap. With `half` (the view's half vector) and `own_rel_sq` (its whole texture variance,
        relative, the lobe correction's included), Cov(gᵢ, ḡ) = own_rel_sq · mean over j of
        excess(|hᵢ − hⱼ|) |Aᵢ ∩ Aⱼ| / Aⱼ (`glint_excess`). On a glossy sample every view of the lobe has its half
        vector within a degree of the normal: most of their glint error is one error of them all.

        A view's overlaps are taken once (its row is built again once E⊥ brackets it), over at most MAX_VIEWS
        views spread over those seen."""
        if not self.n or self.share <= 0:
            return 0.0
        if point_id not in self._common:
            overlaps, halves = self._overlaps(grid)
            self._common[point_id] = float(np.mean(overlaps)) / abs(float(np.linalg.det(grid)))
            excess = 0.0
            if half is not None:
                apart = np.degrees(np.arccos(np.clip(halves @ half, -1.0, 1.0)))
                bins = np.append(self.glint_excess(), 0.0)[np.searchsorted(GLINT_BINS_DEG, apart)]
                excess = float(np.mean(bins * overlaps))
            self._shared[point_id] = own_rel_sq * excess
        scale = self.share * self._block_area / self.n
        static_mean = scale * float(np.mean(list(self._common.values())))
        glint_mean = float(np.mean(list(self._shared.values())))
        return (max(2.0 * scale * self._common[point_id] - static_mean, 0.0)
                + 2.0 * self._shared[point_id] - glint_mean)

    def _overlaps(self, grid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """|A ∩ Aⱼ| / Aⱼ for this view's footprint A and the views seen (at most MAX_VIEWS of them), and their half
        vectors."""
        n = self.n
        rows, cols = self._shape or (1, 1)
        steps = (np.arange(OVERLAP_GRID) + 0.5) / OVERLAP_GRID - 0.5
        gx, gy = np.meshgrid(steps * cols, steps * rows)
        sx = grid[0, 0] * gx.ravel() + grid[0, 1] * gy.ravel()             # this view's footprint on the sample
        sy = grid[1, 0] * gx.ravel() + grid[1, 1] * gy.ravel()
        views = slice(0, n, -(-n // MAX_VIEWS))
        inv, areas = self._inverse[views], self._areas[views]
        lx = inv[:, 0, 0, None] * sx + inv[:, 0, 1, None] * sy               # in each view's own grid
        ly = inv[:, 1, 0, None] * sx + inv[:, 1, 1, None] * sy
        inside = ((np.abs(lx) <= cols / 2.0) & (np.abs(ly) <= rows / 2.0)).mean(axis=1)
        return np.minimum(inside * abs(np.linalg.det(grid)) / areas, 1.0), self._halves[views]


def _resized(a: np.ndarray, rows: int) -> np.ndarray:
    """`a` with room for `rows` entries along its first axis (its entries kept)."""
    out = np.empty((rows, *a.shape[1:]))
    out[:len(a)] = a
    return out
