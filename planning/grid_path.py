"""A collision-free path over an elevation grid at a given altitude, shortened by line of sight.

The vehicle's knowledge of the terrain is a 2.5D grid: each cell's obstacle top and the
variance of that estimate (:class:`lsd.elevation.map.ElevationMap` keeps both). A cell is
passable at an altitude when the highest obstacle within the vehicle's radius, raised by
``k_sigma`` standard deviations and a margin, is below that altitude. Unobserved cells are
never passable: the vehicle does not fly where it has not looked.

The clearance itself is :mod:`planning.clearance`. The shortest path between two cells over
the passable ones is a graph search
(:func:`scipy.sparse.csgraph.dijkstra` over the 8-connected grid), then shortened to the
fewest waypoints that still see each other (the line-of-sight step of section III-D).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

# Samples per cell along a line-of-sight test: fine enough that a segment cannot cross a
# blocked cell's corner unseen by more than a quarter of a cell.
_SAMPLES_PER_CELL = 4


@dataclass(frozen=True, slots=True)
class GridPath:
    """A path found on the grid.

    Attributes:
        cells: (N, 2) int64 grid indices of every cell along the shortest path, start first.
        waypoints: (K, 2) float64 world x, y (ENU m) of the line-of-sight waypoints, from the
            exact start to the exact goal.
        waypoint_cells: (K,) int64 index into ``cells`` of each waypoint (for refining a
            segment with the cells between two waypoints).
        length: metres along ``waypoints``.
    """

    cells: np.ndarray
    waypoints: np.ndarray
    waypoint_cells: np.ndarray
    length: float


def free_cells(clearance: np.ndarray, altitude: float, margin: float) -> np.ndarray:
    """(n0, n1) bool: cells a vehicle at ``altitude`` (ENU z, m) passes over with ``margin``
    metres between it and everything within its radius."""
    return clearance + margin < altitude


def _cell_of(xy: np.ndarray, origin: np.ndarray, resolution: float) -> np.ndarray:
    return np.floor((np.asarray(xy, dtype=np.float64) - origin) / resolution).astype(np.int64)


def _lookup(free: np.ndarray, cells: np.ndarray) -> np.ndarray:
    """``free[cells]`` with every cell outside the grid blocked; cells (..., 2)."""
    n0, n1 = free.shape
    i, j = cells[..., 0], cells[..., 1]
    inside = (i >= 0) & (i < n0) & (j >= 0) & (j < n1)
    out = np.zeros(i.shape, dtype=bool)
    out[inside] = free[i[inside], j[inside]]
    return out


def visible(
    free: np.ndarray, origin: np.ndarray, resolution: float, a: np.ndarray, b: np.ndarray
) -> np.ndarray:
    """Which segments from ``a`` to each of ``b`` stay over free cells.

    Args:
        free: (n0, n1) bool passable cells.
        origin: (2,) world x, y of the corner of cell [0, 0], m.
        resolution: cell size, m.
        a: (2,) start of every segment, world m.
        b: (J, 2) ends, world m.

    Returns:
        (J,) bool.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.atleast_2d(np.asarray(b, dtype=np.float64))
    longest = float(np.max(np.hypot(*(b - a).T), initial=0.0))
    samples = max(2, int(math.ceil(longest / resolution * _SAMPLES_PER_CELL)) + 1)
    t = np.linspace(0.0, 1.0, samples)[:, None, None]
    points = a + t * (b - a)[None, :, :]
    return _lookup(free, _cell_of(points, origin, resolution)).all(axis=0)


def line_cells(origin: np.ndarray, resolution: float, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 2) int64 the cells the segment from ``a`` to ``b`` (world m) passes over, in order
    from ``a``, sampled as :func:`visible` samples it."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    samples = max(2, int(math.ceil(np.hypot(*(b - a)) / resolution * _SAMPLES_PER_CELL)) + 1)
    t = np.linspace(0.0, 1.0, samples)[:, None]
    cells = _cell_of(a + t * (b - a), origin, resolution)
    changed = np.ones(len(cells), dtype=bool)
    changed[1:] = np.any(cells[1:] != cells[:-1], axis=1)
    return cells[changed]


def _grid_graph(free: np.ndarray, resolution: float) -> coo_matrix:
    """The 8-connected graph of the free cells, edge weights in metres."""
    n0, n1 = free.shape
    ids = np.arange(n0 * n1).reshape(n0, n1)
    rows, cols, weights = [], [], []
    for di, dj in ((0, 1), (1, 0), (1, 1), (1, -1)):
        src_i = slice(0, n0 - di)
        dst_i = slice(di, n0)
        src_j = slice(max(0, -dj), n1 - max(0, dj))
        dst_j = slice(max(0, dj), n1 - max(0, -dj))
        both = free[src_i, src_j] & free[dst_i, dst_j]
        if di and dj:
            # No corner cutting: a diagonal step needs both cells beside it free too.
            both &= free[src_i, dst_j] & free[dst_i, src_j]
        rows.append(ids[src_i, src_j][both])
        cols.append(ids[dst_i, dst_j][both])
        weights.append(np.full(int(both.sum()), resolution * math.hypot(di, dj)))
    n = n0 * n1
    return coo_matrix(
        (np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)
    )


def plan_path(
    free: np.ndarray,
    origin: np.ndarray,
    resolution: float,
    start: np.ndarray,
    goal: np.ndarray,
) -> GridPath | None:
    """The shortest path over free cells from ``start`` to ``goal``, shortened by line of sight.

    Args:
        free: (n0, n1) bool passable cells (:func:`free_cells`).
        origin: (2,) world x, y of the corner of cell [0, 0], m.
        resolution: cell size, m.
        start, goal: (2,) world x, y, m. Their own cells count as free (the vehicle is
            already at the start; the goal is the column it is cleared to descend).

    Returns:
        The :class:`GridPath`, or None when the goal cannot be reached or either end is
        outside the grid.
    """
    origin = np.asarray(origin, dtype=np.float64)
    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    n0, n1 = free.shape
    s_cell, g_cell = _cell_of(start, origin, resolution), _cell_of(goal, origin, resolution)
    for c in (s_cell, g_cell):
        if not (0 <= c[0] < n0 and 0 <= c[1] < n1):
            return None
    free = free.copy()
    free[tuple(s_cell)] = free[tuple(g_cell)] = True
    s_id, g_id = s_cell[0] * n1 + s_cell[1], g_cell[0] * n1 + g_cell[1]
    graph = _grid_graph(free, resolution).tocsr()
    dist, pred = dijkstra(graph, directed=False, indices=s_id, return_predecessors=True)
    if not np.isfinite(dist[g_id]):
        return None
    # Walking the predecessors back is sequential by nature; it visits the path's cells only.
    chain = [g_id]
    while chain[-1] != s_id:
        chain.append(int(pred[chain[-1]]))
    ids = np.array(chain[::-1], dtype=np.int64)
    cells = np.stack([ids // n1, ids % n1], axis=1)
    centres = origin + (cells + 0.5) * resolution
    centres[0], centres[-1] = start, goal
    keep = [0]
    # Greedy line of sight: from each kept waypoint jump to the farthest path cell it sees.
    while keep[-1] < len(centres) - 1:
        here = keep[-1]
        seen = visible(free, origin, resolution, centres[here], centres[here + 1 :])
        farthest = int(np.flatnonzero(seen)[-1]) if seen.any() else 0
        keep.append(here + 1 + farthest)
    index = np.array(keep, dtype=np.int64)
    waypoints = centres[index]
    length = float(np.hypot(*np.diff(waypoints, axis=0).T).sum())
    return GridPath(cells=cells, waypoints=waypoints, waypoint_cells=index, length=length)
