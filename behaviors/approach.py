"""The approach to the chosen site along a planned trajectory (Mittal et al., section III-D)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.base import Point, VehicleAction, horizontal_distance, reached
from behaviors.ports import ApproachPlanner, Clock, Trajectory, VehiclePort

if TYPE_CHECKING:
    from lsm.area import OperatingArea

_AREA_SAMPLE = 0.25  # s between the trajectory samples checked against the operating area


class FlyApproachTrajectory(VehicleAction):
    """Fly to above the chosen site along a trajectory planned over the known terrain.

    On its first tick with a position it asks the planner for a trajectory from the vehicle
    to ``(site.x, site.y, site.z + min_height)`` or higher where the planner's margin over
    the map needs it (descending on the way from the cruise
    altitude, so that the descent overlaps the traverse; climbing over its start first from
    a low hover), then streams the trajectory's
    position and velocity to ``vehicle.follow`` on every tick, in clock time from that tick.
    Used as the first child of a Fallback whose second child is the thesis's
    :class:`behaviors.flight.NavigateToSite` (climb to the clear altitude, traverse): a
    FAILURE here hands over to it.

    * SUCCESS: the trajectory has run out and the vehicle is within ``acceptance_radius`` of
      its end
    With an operating ``area``, a trajectory that leaves it (or comes within its margin of
    the edge; checked every 0.25 s of it) is refused: the Fallback's straight traverse,
    which GetLandingSite chose inside the area, is flown instead.

    * FAILURE: no site on the blackboard; no trajectory (the planner's reason), or one
      leaving the operating area; the vehicle
      strays more than ``max_tracking_error`` m from the trajectory; the follow command denied
      or unanswered
    * RUNNING: flying the trajectory, or settling at its end
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        planner: ApproachPlanner,
        *,
        min_height: float = 10.0,
        acceptance_radius: float = 1.0,
        max_tracking_error: float = 5.0,
        command_timeout: float = 5.0,
        area: OperatingArea | None = None,
    ) -> None:
        super().__init__(
            name, vehicle, clock, command_timeout=command_timeout, phase="navigate_to_site"
        )
        self.planner = planner
        self.area = area
        self.min_height = float(min_height)
        self.acceptance_radius = float(acceptance_radius)
        self.max_tracking_error = float(max_tracking_error)
        self.trajectory: Trajectory | None = None
        self.goal: Point | None = None
        self.started_at = 0.0
        self.blackboard.register_key(key=keys.LANDING_SITE, access=Access.READ)

    def initialise(self) -> None:
        super().initialise()
        self.trajectory = None
        self.goal = None

    def _plan(self, position: Point) -> str | None:
        site = self.blackboard.get(keys.LANDING_SITE)
        if site is None:
            return "no landing site chosen"
        goal = (site.x, site.y, site.z + self.min_height)
        planned = self.planner.plan(position, goal)
        if isinstance(planned, str):
            return planned
        if self.area is not None:
            times = np.arange(_AREA_SAMPLE, planned.duration + _AREA_SAMPLE, _AREA_SAMPLE)
            xy = np.array([planned.state_at(min(t, planned.duration))[0][:2] for t in times])
            if len(xy) and not self.area.contains(xy).all():
                return "the planned trajectory leaves the geofence"
        # The planner may end higher than asked, to keep its margin over an obstacle beside
        # the site: arrival is judged at the trajectory's end.
        self.trajectory, self.goal = planned, planned.state_at(planned.duration)[0]
        self.started_at = self.clock.now()
        return None

    def update(self) -> Status:
        position = self.vehicle.state.position
        if position is None:
            self.feedback_message = "waiting for the vehicle position"
            return Status.RUNNING
        if self.trajectory is None:
            why = self._plan(position)
            if why is not None:
                return self.fail(why)
        trajectory, goal = self.trajectory, self.goal
        elapsed = self.clock.now() - self.started_at
        target, velocity = trajectory.state_at(elapsed)
        error = horizontal_distance(position, target)
        if error > self.max_tracking_error:
            return self.fail(f"{error:.1f} m off the trajectory at {elapsed:.1f} s")
        handle = self.vehicle.follow(*target, *velocity)
        if self.handle is None:
            self.command(handle)  # later samples ride on the same command
        problem = self.command_problem()
        if problem is not None:
            return self.fail(problem)
        if elapsed >= trajectory.duration and reached(position, goal, self.acceptance_radius):
            self.feedback_message = "arrived"
            return Status.SUCCESS
        self.feedback_message = (
            f"trajectory {min(elapsed, trajectory.duration):.1f}/{trajectory.duration:.1f} s, "
            f"{horizontal_distance(position, goal):.1f} m to go"
        )
        return Status.RUNNING
