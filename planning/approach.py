"""The approach to a landing site: grid path, line of sight, minimum snap, checked against the map.

:func:`plan_approach` is the whole of section III-D for a 2.5D map: a path over the cells the
vehicle can pass at its altitude, its line-of-sight waypoints, and a minimum-snap trajectory
through them within the speed and acceleration limits. Most approaches cross open ground, so
the straight line is tried first and checked cell by cell; only when it is blocked is a graph
searched, first on a coarser grid whose cells are at least as high as the fine cells they cover
(so a coarse path is a fine path too), then, if that finds none, on the map's own cells.

A smooth trajectory can cut a corner that the straight segments did not; each sample is
therefore checked against the map's own cells, and a segment that grazes an obstacle gets the
path's middle cell as an extra waypoint (Richter et al.'s remedy), a few times at most.
When no path or no clean trajectory exists the answer says why, and the caller keeps the
thesis's climb, traverse and descent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planning.clearance import ObstacleHeights, clearance_at, pooled_clearance
from planning.grid_path import GridPath, _cell_of, free_cells, line_cells, plan_path
from planning.min_snap import (
    SAMPLES_PER_SEGMENT,
    Trajectory,
    concatenate,
    cruise_trajectory,
)

GOAL_SLACK = 0.1
"""m a raised goal is put above the margin over its obstacles: every sample of a trajectory
must be strictly above the margin."""


@dataclass(frozen=True, slots=True)
class ApproachPlan:
    """The outcome of :func:`plan_approach`.

    Attributes:
        trajectory: the trajectory (ENU m, from the start to above the site), or None.
        path: the grid path it follows, or None.
        waypoints: (K, 3) ENU waypoints the trajectory passes through, or None.
        reason: '' when planned; otherwise why not, in one line.
    """

    trajectory: Trajectory | None
    path: GridPath | None
    waypoints: np.ndarray | None
    reason: str = ""

    @property
    def ok(self) -> bool:
        return self.trajectory is not None


def _with_altitudes(xy: np.ndarray, z0: float, z1: float) -> np.ndarray:
    """Waypoints in 3D: from below the goal's altitude a vertical climb over the start first,
    then the path at the goal's altitude; from above it, the altitude falls in proportion to
    the distance flown. Either way the path is never below ``z1``."""
    if z0 < z1:
        climbed = np.column_stack([xy, np.full(len(xy), z1)])
        return np.vstack([[xy[0, 0], xy[0, 1], z0], climbed])
    along = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])
    share = along / along[-1] if along[-1] > 0 else np.zeros_like(along)
    return np.column_stack([xy, z0 + (z1 - z0) * share])


def search_factors(radius: float, resolution: float) -> tuple[int, ...]:
    """Coarsening factors of the graph search, tried in turn (1: the map's own cells). A
    coarse cell of about half the vehicle's radius keeps the search ~10 times smaller at the
    cost of about a coarse cell of extra lateral margin (see
    :func:`planning.clearance.pooled_clearance`)."""
    factor = max(1, int(round(radius / (2.0 * resolution))))
    return (factor, 1) if factor > 1 else (1,)


def _first_collision(
    trajectory: Trajectory, height: ObstacleHeights, reach: float, origin: np.ndarray,
    resolution: float, margin: float, start_cell: np.ndarray,
) -> int | None:
    """The leg (pair of waypoints) of the first sample below the clearance (+ margin), or
    None."""
    t = np.linspace(0.0, trajectory.duration, SAMPLES_PER_SEGMENT * len(trajectory.durations))
    p = trajectory.sample(t)
    cells = _cell_of(p[:, :2], origin, resolution)
    needed = clearance_at(height, cells, reach) + margin
    # The start column is where the vehicle already is: it is not an obstacle to itself.
    at_start = np.all(cells == start_cell, axis=1)
    hit = (p[:, 2] <= needed) & ~at_start
    if not hit.any():
        return None
    first = int(np.flatnonzero(hit)[0])
    segment = int(np.searchsorted(trajectory.knots, t[first], side="right") - 1)
    return trajectory.leg_of(min(segment, len(trajectory.durations) - 1))


def _straight_path(
    height: ObstacleHeights, reach: float, origin: np.ndarray, resolution: float,
    start: np.ndarray, goal: np.ndarray, altitude: float, margin: float,
) -> GridPath | None:
    """The direct line from ``start`` to ``goal`` as a path, when every cell it passes over is
    free at ``altitude`` (the two end cells count as free, as in :func:`plan_path`)."""
    cells = line_cells(origin, resolution, start, goal)
    ends = np.all(cells == cells[0], axis=1) | np.all(cells == cells[-1], axis=1)
    clear = clearance_at(height, cells, reach) + margin < altitude
    if not np.all(clear | ends):
        return None
    return GridPath(cells=cells, waypoints=np.array([start, goal]),
                    waypoint_cells=np.array([0, len(cells) - 1], dtype=np.int64),
                    length=float(np.hypot(*(goal - start))))


def _crossing_altitude(
    height: ObstacleHeights, reach: float, origin: np.ndarray, resolution: float,
    start: np.ndarray, goal: np.ndarray, margin: float,
) -> float:
    """The lowest altitude at which the straight line from ``start`` to ``goal`` keeps
    ``margin`` over every mapped top within ``reach`` (its two end cells aside, as in
    :func:`_straight_path`); inf when it crosses an unobserved cell."""
    cells = line_cells(origin, resolution, start, goal)
    ends = np.all(cells == cells[0], axis=1) | np.all(cells == cells[-1], axis=1)
    if ends.all():
        return -np.inf
    return float(clearance_at(height, cells[~ends], reach).max()) + margin


def plan_approach(
    start: np.ndarray,
    goal: np.ndarray,
    top: np.ndarray,
    variance: np.ndarray,
    origin: np.ndarray,
    resolution: float,
    radius: float,
    margin: float,
    max_speed: float,
    max_acceleration: float,
    k_sigma: float = 2.0,
    refinements: int = 6,
    max_climb: float | None = None,
    max_descent: float | None = None,
) -> ApproachPlan:
    """Plan a trajectory from ``start`` to ``goal`` over the known terrain.

    Args:
        start: (3,) ENU m, the vehicle.
        goal: (3,) ENU m, the point above the site to reach; raised where an obstacle
            within ``radius`` of it is less than ``margin`` below it (the trajectory's end
            is where it arrives).
        top, variance: (n0, n1) obstacle top (ENU z, NaN unknown) and its variance (m^2)
            per cell of the vehicle's map.
        origin: (2,) world x, y of the corner of cell [0, 0], m.
        resolution: cell size, m.
        radius: vehicle radius plus lateral margin, m.
        margin: vertical margin over every obstacle, m.
        max_speed, max_acceleration: limits, m/s and m/s^2.
        max_climb, max_descent: vertical speed limits, m/s (None: ``max_speed`` only).
        k_sigma: standard deviations of each cell's uncertainty added to its top.
        refinements: how many extra waypoints may be inserted where the smooth trajectory
            cuts a corner.

    Returns:
        An :class:`ApproachPlan`; ``reason`` says why when there is no trajectory.
    """
    start = np.asarray(start, dtype=np.float64)
    goal = np.asarray(goal, dtype=np.float64)
    origin = np.asarray(origin, dtype=np.float64)
    height = ObstacleHeights(top, variance, k_sigma)
    reach = radius / resolution
    # An obstacle beside the site may need more than the goal's height for the margin: the
    # goal is raised to clear it, so that the margin holds to the trajectory's very end (the
    # descent below it is the vertical one of every approach).
    beside = clearance_at(height, _cell_of(goal[:2], origin, resolution)[None], reach)[0]
    if np.isfinite(beside) and beside + margin >= goal[2]:
        goal = np.array([goal[0], goal[1], beside + margin + GOAL_SLACK])
    # The path is planned at the goal's altitude: the vehicle climbs to it over the start
    # first, or comes down to it along the path, so it is never lower on the way.
    altitude = goal[2]
    n0, n1 = height.shape
    path, cell_size = None, resolution
    if all(0 <= c[0] < n0 and 0 <= c[1] < n1
           for c in (_cell_of(p[:2], origin, resolution) for p in (start, goal))):
        path = _straight_path(height, reach, origin, resolution, start[:2], goal[:2],
                              altitude, margin)
        for factor in search_factors(radius, resolution) if path is None else ():
            free = free_cells(pooled_clearance(height.grid(), reach, factor), altitude, margin)
            path = plan_path(free, origin, resolution * factor, start[:2], goal[:2])
            if path is not None:
                cell_size = resolution * factor
                break
        if path is None:
            # Nothing around at the goal's altitude (ground rising between, a site in a
            # hollow): straight over, as high as the mapped tops under the line need, the
            # goal raised with it (the vertical descent below it follows).
            over = _crossing_altitude(height, reach, origin, resolution, start[:2], goal[:2],
                                      margin)
            if np.isfinite(over):
                altitude = max(altitude, over + GOAL_SLACK)
                goal = np.array([goal[0], goal[1], altitude])
                path = _straight_path(height, reach, origin, resolution, start[:2],
                                      goal[:2], altitude, margin)
    climb = 1 if start[2] < goal[2] else 0  # the vertical climb is trajectory segment 0
    if path is None:
        return ApproachPlan(None, None, None, f"no path over the known terrain at "
                            f"{altitude:.1f} m (radius {radius:g} m, margin {margin:g} m)")
    index = list(path.waypoint_cells)
    centres = origin + (path.cells + 0.5) * cell_size
    centres[0], centres[-1] = start[:2], goal[:2]
    start_cell = _cell_of(start[:2], origin, resolution)
    limits = (max_speed, max_acceleration, max_climb, max_descent)
    for _ in range(refinements + 1):
        waypoints = _with_altitudes(centres[index], start[2], goal[2])
        if len(waypoints) < 2 or np.allclose(waypoints[0], waypoints[-1]):
            return ApproachPlan(None, path, None, "already above the site")
        if climb:
            # Climb and stop, then go: one smooth piece through the corner would overshoot
            # the climb by metres to keep its derivatives continuous.
            trajectory = concatenate(
                cruise_trajectory(waypoints[:2], *limits),
                cruise_trajectory(waypoints[1:], *limits),
            )
        else:
            trajectory = cruise_trajectory(waypoints, *limits)
        segment = _first_collision(trajectory, height, reach, origin, resolution, margin,
                                   start_cell)
        if segment is None:
            return ApproachPlan(trajectory, path, waypoints)
        if segment < climb:
            break  # the climb over the start itself grazes something
        segment -= climb
        lo, hi = index[segment], index[segment + 1]
        if hi - lo < 2:
            break
        index.insert(segment + 1, (lo + hi) // 2)
    return ApproachPlan(None, path, None, "the smooth trajectory cuts an obstacle the "
                        "path avoids, even with extra waypoints")
