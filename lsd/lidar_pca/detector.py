"""LiDAR landing-spot detector: PCA planes in growing spherical neighbourhoods
(Loureiro et al., "Emergency Landing Spot Detection Algorithm for UAVs", 2021, sections 4-4.6).

Pipeline: accumulate world-frame clouds (:class:`lsd.pointcloud.CloudAccumulator`) ->
voxel-grid filter (:func:`lsd.pointcloud.voxel_grid`, whose sort order is also the spatial
index: :class:`lsd.pointcloud.ColumnIndex`, our counterpart of the paper's octree) ->
Algorithm 1 on search points (random as in the paper, or a grid covering the cloud) -> reject
z-std above sigma_max -> grade (eq. 6) -> register; the registered spots are re-graded as the
vehicle moves and the best one is the emergency output.

Algorithm 1 is batched over search points and radii, with no Python loop over either. Most
search points fail at r_min, so that step runs first for all of them in a few large numpy
calls (one column-index query, one ``np.add.reduceat`` of the ten moments per sphere, one
stacked ``eigh``, one plane-distance pass); the points that passed then get one cylinder query
of their full reach, per-shell moment sums (``np.bincount``) give the PCA of every sphere
radius at once (one stacked ``eigh``), and one pass over (pair, radius) copies checks every
needed sphere's largest distance from its plane (``np.maximum.at``).

Grades (the paper leaves the 0..20 mapping open; ours is linear):

    g_radius = 20 r / r_max        g_slope = 20 (1 - theta / theta_max)
    g_sigma  = 20 (1 - s / s_max)  g_dist  = 20 max(0, 1 - d / distance_scale)
    spot_grade = sum(g_i w_i) / (20 sum w_i)                          (eq. 6, in [0, 1])

Observation fields: size = accepted radius; roughness = sigma / sigma_max; uncertainty =
1 - (1 - 3 l0 / (l0 + l1 + l2)) (1 - n_min / n), i.e. high when the neighbourhood is not
planar (smallest PCA eigenvalue l0 relative to the total; 3 l0 / sum = 1 for isotropic
scatter) or holds barely n_min points; obstacle altitude = highest point within
radius + obstacle_margin horizontally.

Longer than 500 lines: Algorithm 1's vectorised plane search and its growing-radius
state are one loop; site rules, tiles and judging live beside it (sites.py, tiles.py,
judge.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from lsd.lidar_pca.settings import LidarPcaSettings, SpotWeights
from lsd.pointcloud import (
    CloudAccumulator,
    ColumnIndex,
    VoxelCloud,
    clean_points,
    voxel_grid,
)
from lsm.records import SiteObservation

__all__ = [
    "LidarPcaDetector",
    "LidarPcaSettings",
    "PlaneSearch",
    "SpotTable",
    "SpotWeights",
    "detect_planes",
    "search_points",
    "spot_grades",
]

SOURCE = "lidar_pca"


@dataclass
class SpotTable:
    """Landing spots as parallel arrays (K spots).

    Attributes:
        centre: (K, 3) neighbourhood centroid, ENU metres.
        radius: (K,) accepted neighbourhood radius, metres.
        slope: (K,) plane slope, radians.
        sigma: (K,) z standard deviation of the neighbourhood, metres.
        normal: (K, 3) unit plane normal, z >= 0.
        planarity: (K,) 3 * smallest / sum of the PCA eigenvalues, in [0, 1].
        count: (K,) neighbourhood points.
        obstacle_altitude: (K,) highest point around the spot, ENU z metres.
        timestamp: (K,) clock seconds of detection.
    """

    centre: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    radius: np.ndarray = field(default_factory=lambda: np.empty(0))
    slope: np.ndarray = field(default_factory=lambda: np.empty(0))
    sigma: np.ndarray = field(default_factory=lambda: np.empty(0))
    normal: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    planarity: np.ndarray = field(default_factory=lambda: np.empty(0))
    count: np.ndarray = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    obstacle_altitude: np.ndarray = field(default_factory=lambda: np.empty(0))
    timestamp: np.ndarray = field(default_factory=lambda: np.empty(0))

    def __len__(self) -> int:
        return len(self.radius)

    def take(self, index: np.ndarray) -> SpotTable:
        """The spots selected by an index or boolean mask."""
        return SpotTable(**{k: v[index] for k, v in vars(self).items()})

    @staticmethod
    def concat(a: SpotTable, b: SpotTable) -> SpotTable:
        return SpotTable(**{k: np.concatenate((v, getattr(b, k))) for k, v in vars(a).items()})


@dataclass
class PlaneSearch:
    """Outcome of Algorithm 1 plus the sigma check on one processed cloud.

    Attributes:
        spots: accepted spots (before registration), obstacle altitude filled in.
        seeds: (S,) indices of the search points in the downsampled cloud.
        accepted: (S,) bool, the search point yielded a spot.
        rejected_slope, rejected_points, rejected_step, rejected_edge, rejected_clearance,
            rejected_sigma: why the others failed (too steep at r_min, fewer than n_min
            points, a point off the plane by more than max_step at r_min, the r_min sphere
            runs off the data, an obstacle closer than r_min horizontally, z-std above
            sigma_max).
        pca_fits: PCA fits performed (one per search point and radius step).
    """

    spots: SpotTable
    seeds: np.ndarray
    accepted: np.ndarray
    rejected_slope: int = 0
    rejected_points: int = 0
    rejected_step: int = 0
    rejected_edge: int = 0
    rejected_clearance: int = 0
    rejected_sigma: int = 0
    pca_fits: int = 0

    @property
    def n_accepted(self) -> int:
        return int(self.accepted.sum())

    @property
    def n_rejected(self) -> int:
        return int(len(self.seeds) - self.accepted.sum())


def search_points(
    cloud: np.ndarray,
    settings: LidarPcaSettings,
    rng: np.random.Generator,
    core: tuple[float, float, float, float] | None = None,
) -> np.ndarray:
    """Indices of the search points in ``cloud`` (``(N, 3)``).

    ``random``: ``n_points`` distinct random points (all if fewer). ``grid``: for every
    occupied cell of a horizontal grid of ``grid_spacing`` (default ``r_max``) metres
    (anchored at 0, so the same cells whatever part of a cloud is searched), the cloud
    point nearest the cell centre, so every patch the size of a cell is searched.
    ``core = (xmin, xmax, ymin, ymax)``: only the cells whose centre (random: only the
    points) lie in ``[xmin, xmax) x [ymin, ymax)``; a tile searches its core this way.
    """
    n = len(cloud)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    if settings.seeding == "random":
        pool = np.arange(n) if core is None else np.flatnonzero(_in_box(cloud[:, :2], core))
        k = min(settings.n_points, len(pool))
        return np.sort(pool[rng.choice(len(pool), size=k, replace=False)])
    spacing = settings.grid_spacing or settings.r_max
    xy = cloud[:, :2]
    grid = np.floor(xy / spacing)
    centre = (grid + 0.5) * spacing
    if core is not None:
        inside = np.flatnonzero(_in_box(centre, core))
        if len(inside) < n:
            return inside[search_points(cloud[inside], settings, rng)]
    cell = (grid - grid.min(axis=0)).astype(np.int64)
    cell_id = cell[:, 0] * (int(cell[:, 1].max()) + 1) + cell[:, 1]  # one int key per cell
    offset = np.hypot(xy[:, 0] - centre[:, 0], xy[:, 1] - centre[:, 1])
    order = np.lexsort((offset, cell_id))
    sorted_ids = cell_id[order]
    first = np.flatnonzero(np.r_[True, sorted_ids[1:] != sorted_ids[:-1]])
    return np.sort(order[first])


def _in_box(xy: np.ndarray, box: tuple[float, float, float, float]) -> np.ndarray:
    xmin, xmax, ymin, ymax = box
    return (xy[:, 0] >= xmin) & (xy[:, 0] < xmax) & (xy[:, 1] >= ymin) & (xy[:, 1] < ymax)


class _Pairs:
    """(search point, cloud point) pairs of the vertical cylinders around the search points,
    contiguous per search point, with coordinates relative to the search point. Spheres,
    clearance discs and obstacle discs of any radius up to the cylinder's are masks over
    these pairs, so the cloud is queried once.

    Attributes: owner (P,) search point of each pair; x, y, z (P,) coordinates relative to
    it; shell (P,) index of the smallest of ``radii`` whose
    sphere holds the point (len(radii) beyond the largest); counts (S,) pairs per search
    point; origin (S, 3) the search points; n = S.
    """

    def __init__(
        self,
        coords: np.ndarray,
        index: ColumnIndex,
        seeds: np.ndarray,
        radius: float,
        radii: np.ndarray,
    ):
        self.origin = coords[:, seeds].T
        self.n = len(seeds)
        self.owner, flat, dx, dy = index.cylinders(
            coords[0], coords[1], self.origin[:, :2], radius
        )
        self.x, self.y = dx, dy
        self.z = coords[2][flat]
        self.z -= self.origin[:, 2][self.owner]
        d2 = dx * dx
        d2 += dy * dy
        d2 += self.z * self.z
        self.shell = np.searchsorted(radii * radii, d2, side="left")
        self.counts = np.bincount(self.owner, minlength=self.n)

    def starts(self) -> np.ndarray:
        """First pair of each search point (every one has its own point at distance 0)."""
        return np.cumsum(self.counts) - self.counts


# Upper-triangle moment k of (x, y, z) for each entry of a 3 x 3 covariance.
_COV_ENTRY = np.array([[0, 1, 2], [1, 3, 4], [2, 4, 5]])
# The two coordinates of each of those six second moments (xx, xy, xz, yy, yz, zz).
_MOMENT_I = np.array([0, 0, 0, 1, 1, 2])
_MOMENT_J = np.array([0, 1, 2, 1, 2, 2])


def _pca_planes(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Eigenvalues (..., 3), ascending, and the plane normal (..., 3) of covariances
    (..., 3, 3): the eigenvector of the smallest eigenvalue, turned to point up (z >= 0)."""
    evals, evecs = np.linalg.eigh(cov)
    normal = evecs[..., 0]
    normal *= np.where(normal[..., 2] < 0, -1.0, 1.0)[..., None]
    return evals, normal


def _plane_distance(xyz, mean: np.ndarray, normal: np.ndarray, plane: np.ndarray) -> np.ndarray:
    """(P,) distance of each point from its plane.

    Args:
        xyz: the points' x, y, z, each (P,), in the frame of ``mean``.
        mean, normal: (K, 3) a point on each plane (its centroid) and its unit normal.
        plane: (P,) which plane each point is measured against.
    """
    # distance = p . n - m . n, as one 4-vector dot product per point.
    planes = np.empty((len(mean), 4))
    planes[:, :3] = normal
    planes[:, 3] = -(mean * normal).sum(axis=-1)
    point = np.empty((len(plane), 4))
    for k, coordinate in enumerate(xyz):
        point[:, k] = coordinate
    point[:, 3] = 1.0
    return np.abs(np.einsum("ij,ij->i", point, np.take(planes, plane, axis=0)))


def _shell_pca(pairs: _Pairs, r: int):
    """PCA of every search point's sphere at each of the ``r`` radii at once.

    Points are binned into spherical shells (``pairs.shell``); per-shell moment sums from
    ``np.bincount`` are accumulated over shells, so each sphere's moments cost O(1) and one
    stacked ``eigh`` fits all (S, R) planes.

    Returns count (S, R), centroid relative to the search point (S, R, 3), eigenvalues
    (S, R, 3) ascending, unit normals (S, R, 3) with z >= 0, z std (S, R) and the smallest
    horizontal variance (S, R) (:func:`_horizontal_spread`).
    """
    s = pairs.n
    inside = np.flatnonzero(pairs.shell < r)
    key = pairs.owner[inside] * r
    key += pairs.shell[inside]
    x, y, z = pairs.x[inside], pairs.y[inside], pairs.z[inside]
    # One bincount per moment over contiguous 1-D weights (faster than one over (P, 10)
    # rows once the spheres hold thousands of points).
    weights = (None, x, y, z, x * x, x * y, x * z, y * y, y * z, z * z)
    m = np.empty((s * r, 10))
    for k, w in enumerate(weights):
        m[:, k] = np.bincount(key, w, minlength=s * r)
    m = np.cumsum(m.reshape(s, r, 10), axis=1)
    count = m[..., 0].copy()
    m /= np.maximum(count, 1.0)[..., None]
    mean = m[..., 1:4]
    cov = m[..., 4:10][..., _COV_ENTRY] - mean[..., :, None] * mean[..., None, :]
    evals, normal = _pca_planes(cov)
    zstd = np.sqrt(np.maximum(cov[..., 2, 2], 0.0))
    return count, mean, np.maximum(evals, 0.0), normal, zstd, _horizontal_spread(cov)


def _horizontal_spread(cov: np.ndarray) -> np.ndarray:
    """The smallest eigenvalue of the horizontal (x, y) block of covariances (..., 3, 3):
    the variance of the points across their narrowest horizontal direction, m^2."""
    a, b, c = cov[..., 0, 0], cov[..., 0, 1], cov[..., 1, 1]
    return (a + c) / 2 - np.hypot((a - c) / 2, b)


def _off_data(mean: np.ndarray, spread: np.ndarray, radius, settings: LidarPcaSettings
              ) -> np.ndarray:
    """True where a sphere of ``radius`` runs off the data: its centroid is more than
    max_offset * radius (horizontally) from the search point (a cloud edge or a hole on one
    side), or its points spread across their narrowest horizontal direction less than
    min_spread of a filled disc's (variance r^2 / 4): a strip or a line of returns (a scan
    line, the edge of a flight strip) says nothing of the ground beside it."""
    off = np.zeros(spread.shape, dtype=bool)
    if settings.max_offset is not None:  # centroid relative to the seed
        off |= np.hypot(mean[..., 0], mean[..., 1]) > settings.max_offset * radius
    if settings.min_spread is not None:
        off |= spread < settings.min_spread * np.square(radius) / 4
    return off


def _smooth(evals: np.ndarray, settings: LidarPcaSettings) -> np.ndarray:
    """True where the RMS distance from the PCA plane (the square root of the smallest
    eigenvalue) is within residual_max."""
    if settings.residual_max is None:
        return np.ones(evals.shape[:-1], dtype=bool)
    return evals[..., 0] <= settings.residual_max**2


def _max_plane_distance(pairs: _Pairs, mean, normal, need: np.ndarray) -> np.ndarray:
    """Largest distance of a sphere's points from its plane, (S, R), for the spheres marked
    in ``need`` (S, R) (0 elsewhere; ``need`` is a prefix of radii per search point).

    Every pair is repeated once per needed radius at or above its shell, so all spheres are
    checked in one pass (no loop over radii) and reduced with ``np.maximum.at``.
    """
    s, r = need.shape
    last = need.sum(axis=1) - 1  # the last needed radius (a prefix), -1 for none
    copies = np.maximum(last[pairs.owner] - pairs.shell + 1, 0)
    pair = np.repeat(np.arange(len(copies)), copies)
    total = len(pair)
    # Radius of each copy: the pair's shell, then one more per further copy.
    start = np.cumsum(copies) - copies
    radius = np.arange(total) - np.repeat(start - pairs.shell, copies)
    sphere = pairs.owner[pair] * r + radius
    dist = _plane_distance(
        (pairs.x[pair], pairs.y[pair], pairs.z[pair]),
        mean.reshape(-1, 3),
        normal.reshape(-1, 3),
        sphere,
    )
    out = np.zeros(s * r)
    np.maximum.at(out, sphere, dist)
    return out.reshape(s, r)


@dataclass
class _Growth:
    """Algorithm 1 on one set of pairs: per search point the index of the largest radius
    that passed (-1: none), the fits done, and the PCA of every radius."""

    level: np.ndarray
    fits: int
    count: np.ndarray
    mean: np.ndarray
    evals: np.ndarray
    normal: np.ndarray
    zstd: np.ndarray


def _grow(pairs: _Pairs, radii: np.ndarray, settings: LidarPcaSettings, max_step: float):
    """Grow every search point's sphere over ``radii`` (the Algorithm 1 loop, batched over
    search points and radii): a point stays alive while each larger sphere has n_min points,
    slope <= theta_max, no point farther than max_step from its plane and its points on the
    data around it (:func:`_off_data`). The search points are those
    that passed r_min (:func:`_first_radius`), which is fitted again here."""
    r = len(radii)
    count, mean, evals, normal, zstd, spread = _shell_pca(pairs, r)
    slope = np.arccos(np.minimum(normal[..., 2], 1.0))  # normal z >= 0
    enough = count >= settings.n_min
    fit = enough & (slope <= settings.theta_max) & _smooth(evals, settings)  # a flat plane
    lopsided = _off_data(mean, spread, radii, settings)
    off = np.zeros_like(fit)
    if np.isfinite(max_step):
        # Only spheres a point can reach matter: those after an unbroken run of passes.
        reach = fit & ~lopsided
        need = fit.copy()
        need[:, 1:] &= np.logical_and.accumulate(reach, axis=1)[:, :-1]
        if need.any():
            off = need & (_max_plane_distance(pairs, mean, normal, need) > max_step)
    passed = np.logical_and.accumulate(fit & ~off & ~lopsided, axis=1)
    level = passed.sum(axis=1) - 1
    alive = np.ones_like(fit)  # alive before trying each radius
    alive[:, 1:] = passed[:, :-1]
    fits = int((alive & enough).sum())
    return _Growth(level, fits, count, mean, evals, normal, zstd)


def _first_radius(
    points: np.ndarray,
    index: ColumnIndex,
    work: np.ndarray,
    settings: LidarPcaSettings,
    max_step: float,
) -> tuple[np.ndarray, np.ndarray, int]:
    """Algorithm 1's first step for every search point at once: the r_min sphere's plane.

    The same tests as :func:`_grow` on one radius, in fewer and larger numpy calls (every
    sphere holds its own search point, so each is one non-empty run of pairs and the
    per-sphere sums are one ``np.add.reduceat``; no shells). Small search budgets spend
    their time here, mostly in fixed per-call costs.

    Args:
        points: ``(V, 3)`` indexed cloud (sorted by column).
        index: its column index.
        work: ``(S,)`` search points (rows of ``points``).

    Returns:
        ``(passed, first_fail, fits)``: (S,) bool the sphere passed; (S,) int8 why not
        (1 points, 2 slope, 3 step, 4 edge; 0 passed); PCA fits done.
    """
    s = len(work)
    r0 = settings.radii[0]
    # Rows gathered with np.take: several times faster than fancy indexing of (., 3) arrays.
    origin = np.take(points, work, axis=0)
    owner, flat = index.candidates(origin[:, :2], r0)
    rel = np.take(points, flat, axis=0)
    rel -= np.take(origin, owner, axis=0)
    x, y, z = rel.T
    d2 = x * x
    d2 += y * y
    d2 += z * z
    inside = np.flatnonzero(d2 <= r0 * r0)
    owner = owner[inside]
    rel = np.take(rel, inside, axis=0)
    starts = np.searchsorted(owner, np.arange(s))
    moments = np.empty((len(rel), 10))
    moments[:, 0] = 1.0
    moments[:, 1:4] = rel
    np.multiply(rel[:, _MOMENT_I], rel[:, _MOMENT_J], out=moments[:, 4:])
    # (S, 10) sums over each sphere. A sphere holds its own search point, so its run is not
    # empty, unless rounding lost the point itself (coordinates far from the origin): such
    # runs sum to zero (reduceat would repeat the next run's first row).
    filled = np.bincount(owner, minlength=s) > 0
    m = np.zeros((s, 10))
    if filled.any():
        m[filled] = np.add.reduceat(moments, starts[filled], axis=0)
    count = m[:, 0].copy()
    enough = count >= settings.n_min
    first_fail = np.ones(s, dtype=np.int8)  # 1: fewer than n_min points
    if not enough.any():  # sparse clouds: nothing to fit
        return np.zeros(s, dtype=bool), first_fail, 0
    m /= count[:, None]
    mean = m[:, 1:4]
    cov = m[:, 4:10][:, _COV_ENTRY] - mean[:, :, None] * mean[:, None, :]
    evals, normal = _pca_planes(cov)
    fit = enough & (np.arccos(np.minimum(normal[:, 2], 1.0)) <= settings.theta_max)
    smooth = _smooth(evals, settings)
    lopsided = _off_data(mean, _horizontal_spread(cov), r0, settings)
    off = np.zeros(s, dtype=bool)
    if np.isfinite(max_step) and fit.any():
        dist = _plane_distance(rel.T, mean, normal, owner)
        off = fit & (np.maximum.reduceat(dist, starts) > max_step)
    off |= fit & ~smooth  # points scattered off the plane: counted with the step
    first_fail[enough] = 2
    first_fail[fit] = 3
    first_fail[fit & ~off] = 4
    passed = fit & ~off & ~lopsided
    first_fail[passed] = 0
    return passed, first_fail, int(enough.sum())


def detect_planes(
    cloud: np.ndarray | VoxelCloud,
    settings: LidarPcaSettings,
    rng: np.random.Generator,
    timestamp: float = 0.0,
    core: tuple[float, float, float, float] | None = None,
) -> PlaneSearch:
    """Algorithm 1 (growing spherical neighbourhoods, PCA planes) on a downsampled cloud,
    followed by the sigma_max rejection of section 4.5.

    Args:
        cloud: the :class:`~lsd.pointcloud.VoxelCloud` from
            :func:`~lsd.pointcloud.voxel_grid` (its column index is used as is), or any
            ``(N, 3)`` world cloud, metres (indexed here first: one stable sort).
        settings: detector settings.
        rng: source of the random search points.
        timestamp: clock seconds stamped on the spots.
        core: search only this part of the cloud (see :func:`search_points`).

    A search point grows its sphere from r_min by r_step while the fit has at least n_min
    points, slope <= theta_max and (beyond the paper) no point farther than max_step from the
    plane; the last radius that passed is its spot. A point failing at r_min is rejected.
    Beyond the paper, the spot radius is then cut to the horizontal distance of the nearest
    point farther than max_step from the plane inside the vertical cylinder (a sphere misses
    a tall obstacle beside the spot and the drop at a roof edge), and a spot cut below r_min
    is rejected. One horizontal cylinder query (radius r_max + obstacle_margin + r_step)
    serves every radius, the clearance and the obstacle altitude.
    """
    if isinstance(cloud, VoxelCloud):
        coords, index = cloud.coords, cloud.index
        seeds = search_points(cloud.points, settings, rng, core)
        work = seeds  # positions of the search points in coords
    else:
        cloud = np.asarray(cloud, dtype=np.float64)
        seeds = search_points(cloud, settings, rng, core)
        unsorted = np.ascontiguousarray(cloud.T)
        index, order = ColumnIndex.build(unsorted[0], unsorted[1], settings.r_min / 2.0)
        coords = unsorted[:, order]
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        work = rank[seeds]
    s = len(seeds)
    accepted = np.zeros(s, dtype=bool)
    if s == 0:
        return PlaneSearch(SpotTable(), seeds, accepted)
    radii = np.asarray(settings.radii)
    reach = settings.r_max + settings.obstacle_margin + settings.r_step
    max_step = settings.max_step if settings.max_step is not None else np.inf
    # Most search points fail at r_min (the paper's env II): test r_min on small cylinders
    # first and query the full reach only for the points that passed.
    passed, first_fail, fits = _first_radius(coords.T, index, work, settings, max_step)
    reasons = np.bincount(first_fail, minlength=5)
    if not passed.any():  # every search point failed at r_min (common on rough ground)
        return PlaneSearch(
            SpotTable(), seeds, accepted, rejected_points=int(reasons[1]),
            rejected_slope=int(reasons[2]), rejected_step=int(reasons[3]),
            rejected_edge=int(reasons[4]), pca_fits=fits,
        )  # fmt: skip
    # The points that passed r_min: their full reach, every radius.
    live = np.flatnonzero(passed)
    pairs = _Pairs(coords, index, work[live], reach, radii)
    grow = _grow(pairs, radii, settings, max_step)
    fits += grow.fits - len(live)  # r_min was fitted twice
    pick = (np.arange(len(live)), np.maximum(grow.level, 0))
    best_r = radii[pick[1]]
    best_c = grow.mean[pick] + pairs.origin
    best_n = grow.normal[pick]
    best_e = grow.evals[pick]
    best_z = grow.zstd[pick]
    clearance, obstacle = _clearance_and_obstacle(
        pairs, best_c, best_n, best_r, max_step, settings.obstacle_margin
    )
    np.minimum(best_r, clearance, out=best_r)
    clear = best_r >= settings.r_min - 1e-9
    sigma_ok = clear & (best_z <= settings.sigma_max)
    accepted[live[sigma_ok]] = True
    best_e = best_e[sigma_ok]
    total = best_e.sum(axis=1)
    planarity = 3.0 * best_e[:, 0] / np.where(total > 0, total, 1.0)
    best_n = best_n[sigma_ok]
    spots = SpotTable(
        centre=best_c[sigma_ok],
        radius=best_r[sigma_ok],
        slope=np.arccos(np.minimum(np.maximum(best_n[:, 2], 0.0), 1.0)),
        sigma=best_z[sigma_ok],
        normal=best_n,
        planarity=np.minimum(np.maximum(planarity, 0.0), 1.0),
        count=grow.count[pick][sigma_ok].astype(np.int64),
        obstacle_altitude=obstacle[sigma_ok],
        timestamp=np.full(len(best_n), float(timestamp)),
    )
    return PlaneSearch(
        spots=spots,
        seeds=seeds,
        accepted=accepted,
        rejected_slope=int(reasons[2]),
        rejected_points=int(reasons[1]),
        rejected_step=int(reasons[3]),
        rejected_edge=int(reasons[4]),
        rejected_clearance=int(len(live) - clear.sum()),
        rejected_sigma=int((clear & ~sigma_ok).sum()),
        pca_fits=fits,
    )


def _clearance_and_obstacle(
    pairs: _Pairs,
    centres: np.ndarray,
    normals: np.ndarray,
    radii: np.ndarray,
    max_step: float,
    margin: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Per search point (S,): the horizontal distance from the spot centre to the nearest
    point farther than ``max_step`` from the spot plane within its radius (the radius if
    none), and the highest point within radius + margin (the centre's z if none)."""
    counts = pairs.counts
    c = centres - pairs.origin  # spot centres relative to their search points
    hx = pairs.x - np.repeat(c[:, 0], counts)
    hy = pairs.y - np.repeat(c[:, 1], counts)
    hz = pairs.z - np.repeat(c[:, 2], counts)
    h2 = hx * hx
    h2 += hy * hy
    height = hx * np.repeat(normals[:, 0], counts)
    height += hy * np.repeat(normals[:, 1], counts)
    height += hz * np.repeat(normals[:, 2], counts)
    starts = pairs.starts()
    # Squared horizontal distance of the points off the plane within the radius.
    blocking = np.where(
        (np.abs(height) > max_step) & (h2 <= np.repeat(radii * radii, counts)), h2, np.inf
    )
    clearance = np.minimum(radii, np.sqrt(np.minimum.reduceat(blocking, starts)))
    hz[h2 > np.repeat((radii + margin) ** 2, counts)] = -np.inf
    obstacle = centres[:, 2] + np.maximum(np.maximum.reduceat(hz, starts), 0.0)
    return clearance, obstacle


def spot_grades(
    spots: SpotTable,
    settings: LidarPcaSettings,
    vehicle_position: np.ndarray | None = None,
) -> np.ndarray:
    """Spot grade (paper eq. 6) of every spot, ``(K,)`` in [0, 1], higher is better.

    Without a (finite) vehicle position the distance grade is 20 for every spot.
    """
    vehicle_position = _finite_or_none(vehicle_position)
    w = settings.weights
    g_r = 20.0 * np.clip(spots.radius / settings.r_max, 0.0, 1.0)
    g_s = 20.0 * np.clip(1.0 - spots.slope / settings.theta_max, 0.0, 1.0)
    g_z = 20.0 * np.clip(1.0 - spots.sigma / settings.sigma_max, 0.0, 1.0)
    if vehicle_position is None:
        g_d = np.full(len(spots), 20.0)
    else:
        pos = np.asarray(vehicle_position, dtype=np.float64)
        d = np.linalg.norm(spots.centre[:, :2] - pos[:2], axis=1)
        g_d = 20.0 * np.clip(1.0 - d / settings.distance_scale, 0.0, 1.0)
    num = g_r * w.radius + g_s * w.slope + g_z * w.sigma + g_d * w.distance
    return num / (20.0 * (w.radius + w.slope + w.sigma + w.distance))


def _finite_or_none(position: np.ndarray | None) -> np.ndarray | None:
    """A (3,) finite position, or None (bad pose data is ignored, not raised)."""
    if position is None:
        return None
    pos = np.asarray(position, dtype=np.float64).reshape(-1)
    return pos if pos.size >= 3 and np.isfinite(pos[:3]).all() else None


def _dedupe(spots: SpotTable, settings: LidarPcaSettings) -> SpotTable:
    """Keep, among spots closer than merge_distance or whose discs overlap, the
    better-graded ones (greedy, best first)."""
    if len(spots) < 2:
        return spots
    from lsd.lidar_pca.sites import thin_discs

    ranked = spots.take(np.argsort(-spot_grades(spots, settings), kind="stable"))
    return ranked.take(thin_discs(ranked.centre[:, :2], ranked.radius, settings.merge_distance))


class LidarPcaDetector:
    """Stateful LiDAR detector: accumulate scans, process, register and re-grade spots.

    Feed world-frame scans with :meth:`add_scan` (or whole clouds with :meth:`process`); both
    return the observations of the spots found when a cloud is processed (re-detections of
    registered spots included). :meth:`best_spot` is the paper's
    emergency output. Bad rows (NaN/inf) are dropped and counted in :attr:`counters`, never
    raised; so is a whole cloud too wide for int64 voxel keys at its voxel size.
    """

    def __init__(
        self, settings: LidarPcaSettings | None = None, rng: np.random.Generator | int = 0
    ) -> None:
        self.settings = settings or LidarPcaSettings()
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        self.accumulator = CloudAccumulator(
            self.settings.travel_distance, self.settings.max_cloud_points
        )
        self.spots = SpotTable()
        self.last_search: PlaneSearch | None = None
        self._last_processed: float | None = None
        self.counters: dict[str, int] = {
            "scans": 0,
            "clouds_processed": 0,
            "points_dropped": 0,
            "planes_accepted": 0,
            "planes_rejected": 0,
            "spots_registered": 0,
            "clouds_dropped": 0,
        }

    def add_scan(
        self, points: np.ndarray, vehicle_position: np.ndarray | None = None, now: float = 0.0
    ) -> list[SiteObservation]:
        """Accumulate one ``(N, 3)`` world scan; process when travel or size says so (or,
        beyond the paper, when ``process_interval`` clock seconds have passed)."""
        self.counters["scans"] += 1
        if self._last_processed is None or not np.isfinite(now):
            self._last_processed = now if np.isfinite(now) else 0.0
        before = self.accumulator.dropped_points
        cloud = self.accumulator.add(points, vehicle_position)
        self.counters["points_dropped"] += self.accumulator.dropped_points - before
        interval = self.settings.process_interval
        if (
            cloud is None
            and interval is not None
            and now - self._last_processed >= interval
            and self.accumulator.status.points
        ):
            cloud = self.accumulator.release()
        if cloud is None:
            return []
        self._last_processed = now
        return self._process_clean(cloud, vehicle_position, now)

    def process(
        self, points: np.ndarray, vehicle_position: np.ndarray | None = None, now: float = 0.0
    ) -> list[SiteObservation]:
        """Process one whole ``(N, 3)`` world cloud now (no accumulation)."""
        cloud, dropped = clean_points(points)
        self.counters["points_dropped"] += dropped
        return self._process_clean(cloud, vehicle_position, now)

    def _process_clean(
        self, cloud: np.ndarray, vehicle_position: np.ndarray | None, now: float
    ) -> list[SiteObservation]:
        s = self.settings
        self.counters["clouds_processed"] += 1
        if len(cloud) < s.n_min:
            self.last_search = None
            return []
        try:
            grid = voxel_grid(cloud, s.voxel_size)
        except ValueError:  # absurdly wide for the voxel size (bogus far returns): dropped
            self.counters["clouds_dropped"] += 1
            self.last_search = None
            return []
        search = detect_planes(grid, s, self.rng, timestamp=now)
        self.last_search = search
        self.counters["planes_accepted"] += search.n_accepted
        self.counters["planes_rejected"] += search.n_rejected
        # The site rules (geometry: step, residual, clearance ring) on the voxel centroids.
        from lsd.lidar_pca.sites import apply_site_rules

        found = _dedupe(apply_site_rules(search.spots, grid.points, None, s)[0], s)
        self.counters["spots_registered"] += len(self._register(found))
        # Every spot of this cloud is reported, re-detections included: the Landing Site
        # Manager matches them to its sites and lowers their verification altitude.
        return self.to_observations(found, vehicle_position)

    def _register(self, new: SpotTable) -> SpotTable:
        """Merge new spots into the register; return the ones that entered it."""
        s = self.settings
        if len(new) == 0:
            return new
        if len(self.spots) and s.merge_distance > 0:
            dist, near = cKDTree(self.spots.centre).query(
                new.centre, distance_upper_bound=s.merge_distance
            )
            clash = np.isfinite(dist)
            g_new = spot_grades(new, s)
            g_old = spot_grades(self.spots, s)
            safe_near = np.where(clash, near, 0)
            better = clash & (g_new > g_old[safe_near])
            drop_old = np.zeros(len(self.spots), dtype=bool)
            drop_old[near[better]] = True
            self.spots = self.spots.take(~drop_old)
            new = new.take(~clash | better)
        merged = SpotTable.concat(self.spots, new)
        if len(merged) > s.max_spots:
            keep = np.sort(np.argsort(-spot_grades(merged, s), kind="stable")[: s.max_spots])
            entered = keep >= len(self.spots)
            new = merged.take(keep[entered])
            merged = merged.take(keep)
        self.spots = merged
        return new

    def grades(self, vehicle_position: np.ndarray | None = None) -> np.ndarray:
        """Current grade of every registered spot, re-scored at the vehicle position."""
        return spot_grades(self.spots, self.settings, vehicle_position)

    def best_spot(self, vehicle_position: np.ndarray | None = None) -> SiteObservation | None:
        """The best registered spot at the vehicle position (the emergency output), or None."""
        if len(self.spots) == 0:
            return None
        best = int(np.argmax(self.grades(vehicle_position)))
        return self.to_observations(self.spots.take(np.array([best])), vehicle_position)[0]

    def observations(self, vehicle_position: np.ndarray | None = None) -> list[SiteObservation]:
        """All registered spots as observations, best grade first."""
        order = np.argsort(-self.grades(vehicle_position), kind="stable")
        return self.to_observations(self.spots.take(order), vehicle_position)

    def to_observations(
        self, spots: SpotTable, vehicle_position: np.ndarray | None = None
    ) -> list[SiteObservation]:
        """Convert spots to :class:`SiteObservation` (fields as in the module docstring).

        Observation altitude is vehicle z - spot z (0 without a vehicle position).
        """
        s = self.settings
        if len(spots) == 0:
            return []
        vehicle_position = _finite_or_none(vehicle_position)
        roughness = np.clip(spots.sigma / s.sigma_max, 0.0, 1.0)
        fewness = np.clip(s.n_min / np.maximum(spots.count, 1), 0.0, 1.0)
        uncertainty = np.clip(1.0 - (1.0 - spots.planarity) * (1.0 - fewness), 0.0, 1.0)
        if vehicle_position is None:
            obs_alt = np.zeros(len(spots))
        else:
            obs_alt = np.maximum(float(np.asarray(vehicle_position)[2]) - spots.centre[:, 2], 0)
        rows = zip(
            spots.centre.tolist(),
            roughness.tolist(),
            uncertainty.tolist(),
            spots.radius.tolist(),
            spots.obstacle_altitude.tolist(),
            obs_alt.tolist(),
            spots.timestamp.tolist(),
            strict=True,
        )
        return [
            SiteObservation(c[0], c[1], c[2], r, u, size, obst, alt, t, SOURCE)
            for c, r, u, size, obst, alt, t in rows
        ]
