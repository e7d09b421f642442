"""The approach planner over the elevation map the vehicle builds in flight.

It satisfies :class:`behaviors.ports.ApproachPlanner` for
:class:`behaviors.approach.FlyApproachTrajectory`: the cells' obstacle tops and their
uncertainty come from the coarse map of :class:`lsd.elevation.ElevationDetector`, the path
and the minimum-snap trajectory from :func:`planning.plan_approach`.
"""

from __future__ import annotations

import numpy as np

from behaviors.settings import ApproachSettings
from lsd.elevation.map import ElevationMap
from planning import Trajectory, plan_approach

Vector = tuple[float, float, float]


class PlannedApproach:
    """A :class:`planning.Trajectory` as the behaviours read it (ENU tuples)."""

    def __init__(self, trajectory: Trajectory, waypoints: np.ndarray) -> None:
        self.trajectory = trajectory
        self.waypoints = waypoints

    @property
    def duration(self) -> float:
        return self.trajectory.duration

    def state_at(self, t: float) -> tuple[Vector, Vector]:
        p = self.trajectory.sample(t)[0]
        v = self.trajectory.sample(t, 1)[0]
        return (float(p[0]), float(p[1]), float(p[2])), (float(v[0]), float(v[1]), float(v[2]))


class MapApproachPlanner:
    """Plans approaches over ``elevation_map`` (read when :meth:`plan` is called), keeping
    ``settings.vertical_margin`` over every mapped top, or ``default_margin`` when that is
    unset (the mission's clear_altitude_buffer, the thesis's z_buffer)."""

    def __init__(self, elevation_map: ElevationMap, settings: ApproachSettings,
                 default_margin: float = 10.0) -> None:
        self.map = elevation_map
        self.settings = settings
        self.margin = (settings.vertical_margin if settings.vertical_margin is not None
                       else float(default_margin))

    def plan(self, start: Vector, goal: Vector) -> PlannedApproach | str:
        m, s = self.map, self.settings
        # A cell's top catches rocks smaller than the cell; its mean stands in where the map
        # has too few points for a top.
        top = np.where(np.isfinite(m.top), m.top, m.mean)
        origin = m.origin_index.astype(np.float64) * m.resolution
        extent = origin + np.array(m.shape) * m.resolution
        if np.any(np.asarray(goal[:2]) < origin) or np.any(np.asarray(goal[:2]) >= extent):
            return "the site is outside the mapped area"
        planned = plan_approach(
            np.asarray(start), np.asarray(goal), top, m.variance, origin, m.resolution,
            radius=s.vehicle_radius, margin=self.margin, max_speed=s.max_speed,
            max_acceleration=s.max_acceleration, k_sigma=s.k_sigma,
            max_climb=s.max_climb_speed, max_descent=s.max_descent_speed,
        )
        if not planned.ok:
            return planned.reason
        return PlannedApproach(planned.trajectory, planned.waypoints)
