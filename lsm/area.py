"""The mission's operating area (an inclusion geofence) in the local ENU frame.

A simple polygon of ENU x, y metres about home, a margin kept inside its edge, an optional
ceiling and no-fly zones (exclusion polygons and circles) inside it, from whose edges the
same margin is kept. Sites, pattern waypoints and straight legs are tested against it, vectorised:
matplotlib's Path for point-in-polygon, numpy for distances to the edges. Used by the
Landing Site Manager (sites outside are rejected) and by the behaviours (search patterns,
pattern centres and the approach stay inside).
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

# matplotlib is imported when an area is first used: the LSM and a mission without a
# geofence do not pay for it at start-up.


class NoFlyCircle(NamedTuple):
    """A round no-fly zone (a mast, a tree, a person): everything within ``radius`` m of the
    centre ``x``, ``y`` (ENU m)."""

    x: float
    y: float
    radius: float


NoFlyZone = tuple[tuple[float, float], ...] | NoFlyCircle
"""A no-fly polygon (ENU x, y m vertices, not closed) or a :class:`NoFlyCircle`."""


@dataclass(frozen=True)
class OperatingArea:
    """Inclusion geofence: ``vertices`` (ENU x, y m, not closed), ``margin`` m kept inside
    the edge, ``max_altitude`` m above home (None: no ceiling), ``exclusions``: no-fly
    zones, polygons (ENU x, y m, not closed) or :class:`NoFlyCircle`, kept out of, ``margin``
    m from their edges too. Zones are numbered in the order of ``exclusions``."""

    vertices: tuple[tuple[float, float], ...]
    margin: float = 0.0
    max_altitude: float | None = None
    exclusions: tuple[NoFlyZone, ...] = ()

    @functools.cached_property
    def _corners(self) -> np.ndarray:
        return np.asarray(self.vertices, dtype=np.float64).reshape(-1, 2)

    @functools.cached_property
    def _path(self):  # matplotlib.path.Path
        return _closed_path(self._corners)

    @functools.cached_property
    def _zones(self) -> list[tuple[object, np.ndarray, np.ndarray]]:
        """Per no-fly polygon: its matplotlib Path and its edges (starts, ends)."""
        zones = []
        for zone in self.exclusions:
            if isinstance(zone, NoFlyCircle):
                continue
            a = np.asarray(zone, dtype=np.float64).reshape(-1, 2)
            zones.append((_closed_path(a), a, np.roll(a, -1, axis=0)))
        return zones

    @functools.cached_property
    def _zone_numbers(self) -> np.ndarray:
        """The number (index in ``exclusions``) of each no-fly polygon of ``_zones``."""
        return np.array([k for k, z in enumerate(self.exclusions)
                         if not isinstance(z, NoFlyCircle)], dtype=int)

    @functools.cached_property
    def _circles(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The no-fly circles as (numbers in ``exclusions``, centres (k, 2), radii (k,)),
        None when there is none."""
        numbers = [k for k, z in enumerate(self.exclusions) if isinstance(z, NoFlyCircle)]
        if not numbers:
            return None
        circles = np.array([self.exclusions[k] for k in numbers], dtype=np.float64)
        return np.array(numbers, dtype=int), circles[:, :2], circles[:, 2]

    def _centre_distance(self, p: np.ndarray) -> np.ndarray:
        """Distances (n, k) of points ``p`` (n, 2) to the no-fly circles' centres."""
        assert self._circles is not None
        d = p[:, None, :] - self._circles[1][None]
        return np.hypot(d[..., 0], d[..., 1])

    @functools.cached_property
    def _edges(self) -> tuple[np.ndarray, np.ndarray]:
        """Every edge a point keeps the margin from: the area's, then the zones' ones."""
        a = self._corners
        b = np.roll(a, -1, axis=0)
        if not self._zones:
            return a, b
        return (np.vstack([a, *(z[1] for z in self._zones)]),
                np.vstack([b, *(z[2] for z in self._zones)]))

    def edge_distance(self, xy: np.ndarray | Sequence[float]) -> np.ndarray:
        """Distance (m) of each point ``xy`` ((n, 2) or (2,)) to the nearest edge (of the
        area or of a no-fly zone)."""
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        a, b = self._edges
        distance = _point_segment_distance(p[:, None, :], a[None], b[None]).min(axis=1)
        if self._circles is not None:
            rim = np.abs(self._centre_distance(p) - self._circles[2][None]).min(axis=1)
            distance = np.minimum(distance, rim)
        return distance

    def contains(self, xy: np.ndarray | Sequence[float]) -> np.ndarray:
        """Per point ``xy`` ((n, 2) or (2,)): inside the polygon, outside every no-fly zone
        and at least ``margin`` m from every edge."""
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        inside = self._path.contains_points(p)
        for path, _, _ in self._zones:
            if inside.any():
                inside &= ~path.contains_points(p)
        if self._circles is not None and inside.any():
            inside &= (self._centre_distance(p) >= self._circles[2][None] + self.margin
                       ).all(axis=1)
        if self.margin > 0 and inside.any():
            inside &= self.edge_distance(p) >= self.margin
        return inside

    def overlaps(self, zone: Sequence[Sequence[float]] | NoFlyCircle) -> bool:
        """True when the polygon (ENU x, y m, not closed) or :class:`NoFlyCircle` and the
        area share any ground (one inside the other counts)."""
        if isinstance(zone, NoFlyCircle):
            centre = np.array([[zone.x, zone.y]])
            if self._path.contains_points(centre)[0]:
                return True
            a = self._corners
            return bool(_point_segment_distance(centre, a, np.roll(a, -1, axis=0)).min()
                        < zone.radius)
        corners = np.asarray(zone, dtype=np.float64).reshape(-1, 2)
        return bool(self._path.intersects_path(_closed_path(corners), filled=True))

    def zone_of(self, xy: np.ndarray | Sequence[float]) -> np.ndarray:
        """Per point ``xy`` ((n, 2) or (2,)): the index (in ``exclusions``) of the first
        no-fly zone it is in or within ``margin`` m of, -1 for none."""
        p = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        out = np.full(len(p), -1)
        for k, (path, a, b) in reversed(list(zip(self._zone_numbers.tolist(), self._zones,
                                                 strict=True))):
            hit = path.contains_points(p)
            if self.margin > 0:
                hit |= _point_segment_distance(p[:, None, :], a[None], b[None]).min(
                    axis=1) < self.margin
            out[hit] = k
        if self._circles is not None:
            numbers, _, radii = self._circles
            hit = self._centre_distance(p) < radii[None] + self.margin
            return _first(out, np.where(hit, numbers[None], _NONE).min(axis=1))
        return out

    def contains_point(self, x: float, y: float) -> bool:
        return bool(self.contains((x, y))[0])

    def leg_inside(self, start: Sequence[float], end: Sequence[float]) -> bool:
        """True when the straight leg ``start`` -> ``end`` (x, y first) stays inside: the
        end is inside with the margin, and the leg crosses no edge and comes no closer to
        one than the margin. A start already closer to the edge than the margin (the
        vehicle drifted there) only has to be inside the polygon, and the leg keeps the
        start's own clearance. A non-convex area can have both ends inside and the leg
        out."""
        s = np.asarray(start[:2], dtype=np.float64)
        e = np.asarray(end[:2], dtype=np.float64)
        if not (self._path.contains_point(s) and self.contains(e)[0]):
            return False
        if any(path.contains_point(s) for path, _, _ in self._zones):
            return False
        a, b = self._edges
        need = self._start_clearance(s)
        if self._circles is not None and self._circles_crossed(s, e, need).any():
            return False
        return _leg_clear(s, e, a, b, need)

    def leg_zone(self, start: Sequence[float], end: Sequence[float]) -> int | None:
        """The index of the first no-fly zone the straight leg ``start`` -> ``end`` enters,
        crosses or comes within the margin of (as :meth:`leg_inside` tests it), or None."""
        s = np.asarray(start[:2], dtype=np.float64)
        e = np.asarray(end[:2], dtype=np.float64)
        need = self._start_clearance(s)
        ends = self.zone_of(np.vstack([s, e]))
        first = None
        for k, (path, a, b) in zip(self._zone_numbers.tolist(), self._zones, strict=True):
            if path.contains_point(s) or ends[1] == k or not _leg_clear(s, e, a, b, need):
                first = k
                break
        if self._circles is not None:
            numbers = self._circles[0]
            hit = self._circles_crossed(s, e, need) | (numbers == ends[1])
            if hit.any() and (first is None or numbers[hit][0] < first):
                first = int(numbers[hit][0])
        return first

    def _circles_crossed(self, s: np.ndarray, e: np.ndarray, need: float) -> np.ndarray:
        """Per no-fly circle: does the leg ``s``-``e`` start in it or come closer to its
        rim than ``need`` m (its closest approach to the centre under radius + need)?"""
        assert self._circles is not None
        _, centres, radii = self._circles
        start_in = self._centre_distance(s[None])[0] < radii
        return start_in | (_point_segment_distance(centres, s[None], e[None])
                           < radii + max(need, 0.0))

    def _start_clearance(self, s: np.ndarray) -> float:
        """The clearance a leg from ``s`` keeps from the edges: the margin, or less for a
        start already closer (the vehicle drifted there); 0 without a margin."""
        if self.margin <= 0:
            return 0.0
        a, b = self._edges
        near = float(_point_segment_distance(s[None], a, b).min())
        if self._circles is not None:
            near = min(near, float(self.edge_distance(s)[0]))
        return min(self.margin, near) - 1e-9

    def route_inside(self, points: Sequence[Sequence[float]]) -> bool:
        """True when every leg of the polyline ``points`` stays inside (see leg_inside)."""
        if len(points) == 1:
            return self.contains_point(points[0][0], points[0][1])
        return all(self.leg_inside(p, q) for p, q in zip(points[:-1], points[1:], strict=True))


_NONE = np.iinfo(int).max  # no zone, in a minimum of zone numbers


def _first(out: np.ndarray, other: np.ndarray) -> np.ndarray:
    """Per point, the lower zone number of ``out`` (-1: none) and ``other`` (_NONE: none)."""
    out = np.where(out < 0, _NONE, out)
    out = np.minimum(out, other)
    return np.where(out == _NONE, -1, out)


def _closed_path(corners: np.ndarray):  # matplotlib.path.Path
    from matplotlib.path import Path

    return Path(np.vstack([corners, corners[:1]]), closed=True)


def _leg_clear(s: np.ndarray, e: np.ndarray, a: np.ndarray, b: np.ndarray, need: float
               ) -> bool:
    """The leg ``s``-``e`` crosses none of the edges ``a``-``b`` and comes no closer to
    them than ``need`` m (no distance checked for ``need`` <= 0)."""
    if _segments_cross(s, e, a, b).any():
        return False
    if need <= 0:
        return True
    # Not crossing: the closest approach of two segments is at one of the four ends.
    near = min(
        float(_point_segment_distance(e[None], a, b).min()),
        float(_point_segment_distance(a, s[None], e[None]).min()),
    )
    return near >= need


def _point_segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distances of points ``p`` to segments ``a``-``b`` (broadcast over leading axes)."""
    ab = b - a
    length2 = np.maximum((ab * ab).sum(axis=-1), 1e-300)
    t = np.clip(((p - a) * ab).sum(axis=-1) / length2, 0.0, 1.0)
    closest = a + t[..., None] * ab
    return np.hypot(*np.moveaxis(p - closest, -1, 0))


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1]) - (
        a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0])


def _segments_cross(s: np.ndarray, e: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per segment ``a[i]``-``b[i]``: does it intersect ``s``-``e`` (touching counts)?"""
    d1, d2 = _cross(a, b, s), _cross(a, b, e)
    d3, d4 = _cross(s, e, a), _cross(s, e, b)
    proper = (d1 * d2 < 0) & (d3 * d4 < 0)
    touch = (
        ((d1 == 0) & _on_segment(a, b, s)) | ((d2 == 0) & _on_segment(a, b, e))
        | ((d3 == 0) & _on_segment(s, e, a)) | ((d4 == 0) & _on_segment(s, e, b))
    )
    return proper | touch


def _on_segment(a: np.ndarray, b: np.ndarray, p: np.ndarray) -> np.ndarray:
    """For collinear points: does ``p`` lie within the bounding box of ``a``-``b``?"""
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    return ((p >= lo) & (p <= hi)).all(axis=-1)


def self_intersection(vertices: Sequence[Sequence[float]]) -> tuple[int, int] | None:
    """The first pair of edges (i, j) of the closed polygon that cross or touch, other than
    neighbours meeting at their shared vertex; None for a simple polygon."""
    a = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
    n = len(a)
    b = np.roll(a, -1, axis=0)
    for i in range(n):
        crosses = _segments_cross(a[i], b[i], a, b)
        crosses[i] = False
        crosses[(i + 1) % n] = crosses[(i - 1) % n] = False
        if n == 3:
            continue
        hit = np.flatnonzero(crosses)
        if len(hit):
            return i, int(hit[0])
    return doubling_back(a)


def doubling_back(vertices: Sequence[Sequence[float]]) -> tuple[int, int] | None:
    """Neighbouring edges (i, j) that overlap along a line (a spike back along the edge),
    which no simple polygon has; None when there are none."""
    a = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
    n = len(a)
    b = np.roll(a, -1, axis=0)
    prev = np.roll(a, 1, axis=0)
    u, v = a - prev, b - a
    cross = u[:, 0] * v[:, 1] - u[:, 1] * v[:, 0]
    back = (cross == 0) & ((u * v).sum(axis=1) < 0)
    if back.any():
        i = int(np.flatnonzero(back)[0])
        return (i - 1) % n, i
    return None
