"""From the planes of Algorithm 1 to sites a 1 m footprint can live with (issue 16): the
site rules on the points around each spot, non-overlapping discs, and the counts that say
how many were found, kept and dropped, and why.

Site rules, checked on the cloud's own points (not the voxel centroids) in the vertical
cylinder of radius ``radius + obstacle_margin`` around each spot, relative to the spot's
plane:

- disc (horizontal distance <= radius): no point farther than ``max_step`` from the plane
  (a step, a hole, anything overhanging the site), RMS distance from the plane within
  ``residual_max``, at least ``n_min`` points;
- clearance ring (radius < distance <= radius + obstacle_margin): no point higher than
  ``obstacle_height`` above the plane (the obstacle altitude the site reports);
- coverage (``max_gap``, :mod:`lsd.lidar_pca.coverage`): disc and ring are covered by
  returns of any class; no return is unknown ground, not clear ground;
- classified clouds (:class:`~lsd.lidar_pca.settings.ClassRules`): disc and ring hold
  only ground points (2), or, with ``roofs``, only building points (6) for a site on a roof;
  vegetation (3-5), water (9), noise (7, 18), unclassified (1) and every other class
  reject it.

A spot whose rules fail at its radius is shrunk to the largest radius of the detector's
radii that passes; below r_min it is dropped, counted by the rule that dropped it.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from lsd.lidar_pca.coverage import coverage_scale, unseen_distance
from lsd.lidar_pca.detector import PlaneSearch, SpotTable, detect_planes, spot_grades
from lsd.lidar_pca.settings import LidarPcaSettings
from lsd.pointcloud import ColumnIndex, thin_by_distance, voxel_grid

# Pairs (spot, point) handled at once: bounds the temporaries of the rule checks.
_PAIRS_PER_BATCH = 4_000_000

DROP_REASONS = ("class", "obstacle", "unseen", "step", "residual", "sparse")


@dataclass
class SiteCounts:
    """How many search points, planes and sites each stage found, kept and dropped."""

    points: int = 0
    search_points: int = 0
    planes: int = 0  # spots Algorithm 1 accepted
    rejected: Counter = field(default_factory=Counter)  # search points that gave no plane
    dropped: Counter = field(default_factory=Counter)  # spots dropped by a site rule
    shrunk: int = 0  # spots kept with a smaller radius by a site rule
    overlapping: int = 0  # spots dropped because a better site's disc overlaps theirs
    beyond_max: int = 0  # sites beyond max_spots, not reported
    kept: int = 0

    def add_search(self, search: PlaneSearch) -> None:
        self.search_points += len(search.seeds)
        self.planes += search.n_accepted
        for reason in ("slope", "points", "step", "edge", "clearance", "sigma"):
            self.rejected[reason] += getattr(search, f"rejected_{reason}")

    def merge(self, other: SiteCounts) -> None:
        self.points += other.points
        self.search_points += other.search_points
        self.planes += other.planes
        self.rejected.update(other.rejected)
        self.dropped.update(other.dropped)
        self.shrunk += other.shrunk

    def summary(self) -> str:
        """One line: found, kept and dropped, and why."""
        rej = ", ".join(f"{k} {v}" for k, v in self.rejected.items() if v) or "none"
        drop = ", ".join(f"{k} {v}" for k, v in self.dropped.items() if v) or "none"
        return (
            f"{self.search_points} search points -> {self.planes} planes (no plane: {rej}) "
            f"-> site rules dropped {sum(self.dropped.values())} ({drop}), shrunk "
            f"{self.shrunk} -> {self.overlapping} dropped for overlapping a better site"
            + (f", {self.beyond_max} beyond max_spots" if self.beyond_max else "")
            + f" -> {self.kept} sites kept"
        )


def is_classified(codes: np.ndarray | None) -> bool:
    """Whether a cloud's classification says anything: it holds ground (2) points."""
    return codes is not None and bool(np.any(codes == 2))


def find_sites(
    points: np.ndarray,
    codes: np.ndarray | None,
    settings: LidarPcaSettings,
    rng: np.random.Generator,
    core: tuple[float, float, float, float] | None = None,
    classified: bool | None = None,
) -> tuple[SpotTable, SiteCounts]:
    """Sites of one cloud (or of the core of a tile): voxel grid on the global lattice,
    Algorithm 1, then the site rules on ``points`` (raw, metres) and their ``codes``.
    Overlaps are not thinned here (:func:`finish_sites` does it over all tiles)."""
    counts = SiteCounts(points=len(points))
    if len(points) < settings.n_min:
        return SpotTable(), counts
    grid = voxel_grid(points, settings.voxel_size, lattice=True)
    search = detect_planes(grid, settings, rng, core=core)
    counts.add_search(search)
    if classified is None:
        classified = is_classified(codes)
    use_codes = codes if (classified and settings.classes.enabled) else None
    spots, dropped, shrunk = apply_site_rules(search.spots, points, use_codes, settings)
    counts.dropped.update(dropped)
    counts.shrunk += shrunk
    return spots, counts


def finish_sites(spots: SpotTable, settings: LidarPcaSettings, counts: SiteCounts) -> SpotTable:
    """Best first (grade, then position, so the order does not depend on tiling), with no
    two discs overlapping (the better stays) and at most ``max_spots``."""
    if len(spots) == 0:
        return spots
    grade = spot_grades(spots, settings)
    order = np.lexsort((spots.centre[:, 1], spots.centre[:, 0], -grade))
    spots = spots.take(order)
    keep = thin_discs(spots.centre[:, :2], spots.radius, settings.merge_distance)
    counts.overlapping += int((~keep).sum())
    spots = spots.take(keep)
    if len(spots) > settings.max_spots:
        counts.beyond_max += len(spots) - settings.max_spots
        spots = spots.take(np.arange(settings.max_spots))
    counts.kept = len(spots)
    return spots


def thin_discs(centres: np.ndarray, radii: np.ndarray, min_distance: float = 0.0) -> np.ndarray:
    """Greedy, in the given order (best first): keep a disc unless a kept one overlaps it
    (centres closer than the sum of the radii, or than ``min_distance``); (N,) bool."""
    return thin_by_distance(centres, min_distance, np.asarray(radii, dtype=np.float64))


def apply_site_rules(
    spots: SpotTable,
    points: np.ndarray,
    codes: np.ndarray | None,
    settings: LidarPcaSettings,
) -> tuple[SpotTable, Counter, int]:
    """The site rules (module docstring) on every spot at once.

    Args:
        spots: Algorithm 1's spots.
        points: (N, 3) the cloud around them, metres.
        codes: (N,) ASPRS classes, or None to judge by geometry alone.

    Returns:
        (spots kept, with their radius shrunk where a rule needed it; Counter of the
        dropped by rule; how many were shrunk).
    """
    dropped: Counter = Counter()
    if len(spots) == 0:
        return spots, dropped, 0
    ring = settings.obstacle_margin
    reach = float(spots.radius.max()) + ring
    pts = np.asarray(points, dtype=np.float64)
    index, order = ColumnIndex.build(pts[:, 0], pts[:, 1], max(reach / 4.0, 0.05))
    x, y, z = (np.ascontiguousarray(pts[order, k]) for k in range(3))
    sorted_codes = None if codes is None else np.asarray(codes)[order]
    per_spot = max(1.0, len(pts) / max(index.shape[0] * index.shape[1], 1)
                   * 16 * reach * reach / max(index.cell, 1e-9) ** 2)
    batch = max(1, int(_PAIRS_PER_BATCH / per_spot))
    limits = [
        _limits(spots.take(np.arange(i, min(i + batch, len(spots)))), x, y, z,
                sorted_codes, index, reach, settings)
        for i in range(0, len(spots), batch)
    ]
    limit = {k: np.concatenate([lim[k] for lim in limits]) for k in limits[0]}
    radii = np.asarray(settings.radii)
    # Coverage (beyond the paper, lsd.lidar_pca.coverage): the nearest unseen node bounds
    # the extent (radius + ring + band).
    if settings.max_gap is not None:
        tree = cKDTree(np.column_stack((x, y)))
        gap, band = coverage_scale(spots.radius, limit["n_disc"], settings)
        unseen = unseen_distance(tree, spots.centre[:, :2], spots.radius + ring + band, gap,
                                 settings.r_min / 4) - band
    else:
        unseen, band = np.full(len(spots), np.inf), np.zeros(len(spots))
    allowed = np.minimum.reduce([spots.radius, limit["step"] - 1e-9,
                                 limit["obstacle"] - ring - 1e-9,
                                 limit["class"] - ring - 1e-9,
                                 unseen - ring - 1e-9])
    # The largest detector radius within what the rules allow (the spot's own if it passed).
    snapped = radii[np.maximum(np.searchsorted(radii, allowed + 1e-9, side="right") - 1, 0)]
    new_r = np.where(allowed >= spots.radius, spots.radius, snapped)
    ok = allowed >= settings.r_min - 1e-9
    if settings.max_gap is not None:
        # A shrunk site's lattice nodes were all seen; its own outer circle is checked now.
        again = np.flatnonzero(ok & (new_r < spots.radius - 1e-9))
        still = unseen_distance(tree, spots.centre[again, :2],
                                new_r[again] + ring + band[again], gap[again],
                                settings.r_min / 4)
        ok[again[np.isfinite(still)]] = False
        unseen[again[np.isfinite(still)]] = -np.inf
    # Flatness and point count of the final disc (a smaller disc has its own).
    final = spots.take(ok)
    final.radius = new_r[ok]
    if len(final):
        flat = [_disc_residual(final.take(np.arange(i, min(i + batch, len(final)))), x, y, z,
                               index, settings) for i in range(0, len(final), batch)]
        rms = np.concatenate([f[0] for f in flat])
        count = np.concatenate([f[1] for f in flat])
        final.obstacle_altitude = np.concatenate([f[2] for f in flat])
    else:
        rms = count = np.empty(0)
    too_rough = np.zeros(len(final), dtype=bool)
    if settings.residual_max is not None:
        too_rough = rms > settings.residual_max
    too_few = count < settings.n_min
    # Reasons of the dropped: the rule binding at r_min.
    why = np.select(
        [limit["class"] - ring <= settings.r_min, limit["obstacle"] - ring <= settings.r_min,
         unseen - ring <= settings.r_min],
        ["class", "obstacle", "unseen"], "step",
    )
    dropped.update(why[~ok].tolist())
    dropped["residual"] += int((too_rough & ~too_few).sum())
    dropped["sparse"] += int(too_few.sum())
    good = ~too_rough & ~too_few
    shrunk = int((final.radius[good] < spots.radius[ok][good] - 1e-9).sum())
    return final.take(good), dropped, shrunk


def _pairs(spots: SpotTable, x, y, z, index: ColumnIndex, reach: float):
    """(owner, index, d, h): spot, point, horizontal distance and height above the spot's
    plane of every point within ``reach`` horizontally of a spot centre."""
    owner, idx, dx, dy = index.cylinders(x, y, spots.centre[:, :2], reach)
    dz = z[idx] - spots.centre[owner, 2]
    n = spots.normal[owner]
    h = dx * n[:, 0] + dy * n[:, 1] + dz * n[:, 2]
    return owner, idx, np.hypot(dx, dy), h, dz


def _limits(spots, x, y, z, codes, index, reach, settings) -> dict[str, np.ndarray]:
    """Per spot, the horizontal distance of the nearest point breaking each rule (inf for
    none): ``step`` (off the plane by more than max_step), ``obstacle`` (higher than
    obstacle_height above it), ``class`` (a class the site may not have)."""
    k = len(spots)
    owner, idx, d, h, _ = _pairs(spots, x, y, z, index, reach)
    out = {}
    max_step = settings.max_step if settings.max_step is not None else np.inf
    high = settings.obstacle_height if settings.obstacle_height is not None else np.inf
    for name, bad in (("step", np.abs(h) > max_step), ("obstacle", h > high)):
        lim = np.full(k, np.inf)
        np.minimum.at(lim, owner[bad], d[bad])
        out[name] = lim
    # Returns in each disc: its point spacing, for the coverage rule.
    out["n_disc"] = np.bincount(owner[d <= spots.radius[owner]], minlength=k)
    lim = np.full(k, np.inf)
    if codes is not None:
        rules = settings.classes
        c = codes[idx]
        ground = np.isin(c, rules.ground)
        roof = np.isin(c, rules.roof) if rules.roofs else np.zeros_like(ground)
        # The site's surface: roof where its r_min disc holds more roof than ground points.
        near = d <= settings.r_min
        on_roof = (np.bincount(owner[near & roof], minlength=k)
                   > np.bincount(owner[near & ground], minlength=k))
        bad = np.where(on_roof[owner], ~roof, ~ground)
        np.minimum.at(lim, owner[bad], d[bad])
    out["class"] = lim
    return out


def _disc_residual(spots, x, y, z, index, settings) -> tuple[np.ndarray, ...]:
    """Per spot, the RMS distance of the disc's points from the spot plane, their count,
    and the obstacle altitude: the highest point within radius + obstacle_margin."""
    ring = settings.obstacle_margin
    owner, _, d, h, dz = _pairs(spots, x, y, z, index, float(spots.radius.max()) + ring)
    inside = d <= spots.radius[owner]
    count = np.bincount(owner[inside], minlength=len(spots))
    sq = np.bincount(owner[inside], h[inside] ** 2, minlength=len(spots))
    rise = np.zeros(len(spots))
    near = d <= spots.radius[owner] + ring
    np.maximum.at(rise, owner[near], dz[near])
    return np.sqrt(sq / np.maximum(count, 1)), count, spots.centre[:, 2] + rise


__all__ = [
    "DROP_REASONS",
    "SiteCounts",
    "apply_site_rules",
    "find_sites",
    "finish_sites",
    "is_classified",
    "thin_discs",
]
