"""Search behaviours (thesis section 3.3.1): fly a rectangle to find sites, move the
pattern to a new random centre."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.base import Point, RouteAction
from behaviors.failsafe import battery_below
from behaviors.ports import Clock, VehiclePort

if TYPE_CHECKING:
    from lsm import LandingSiteManager
    from lsm.area import OperatingArea

PATTERN_SCALES = (1.0, 0.75, 0.5, 0.35, 0.25, 0.15, 0.1)
"""Fractions of the search rectangle tried, largest first, until the pattern (and the leg
to it) lies inside the operating area."""
CENTRE_DRAWS = 100
"""Draws of a new pattern centre before giving up: a centre inside the operating area
(and reachable in a straight leg) that 100 uniform draws over the disc miss lies in under
about 3 % of it, too little to search."""


def rectangle_pattern(
    center: tuple[float, float],
    size: tuple[float, float],
    altitude: float,
    start_near: tuple[float, float] | None = None,
) -> list[Point]:
    """Waypoints of a closed rectangle around ``center``, flown at ``altitude``.

    Args:
        center: ENU x, y of the rectangle centre, m.
        size: width (along x) and height (along y), m.
        altitude: ENU z of every waypoint, m.
        start_near: begin at the corner nearest this x, y (default: the south-west corner).

    Returns:
        five (x, y, z) corners, counter-clockwise, the first repeated at the end.
    """
    cx, cy = center
    hw, hh = size[0] / 2.0, size[1] / 2.0
    corners = [(cx - hw, cy - hh), (cx + hw, cy - hh), (cx + hw, cy + hh), (cx - hw, cy + hh)]
    first = 0
    if start_near is not None:
        sx, sy = start_near
        first = min(range(4), key=lambda i: math.hypot(corners[i][0] - sx, corners[i][1] - sy))
    order = corners[first:] + corners[:first]
    return [(x, y, altitude) for x, y in order + order[:1]]


def random_point_in_disc(
    rng: np.random.Generator, center: tuple[float, float], radius: float
) -> tuple[float, float]:
    """A point drawn uniformly over the disc of ``radius`` m around ``center`` (ENU x, y)."""
    r = radius * math.sqrt(rng.random())
    angle = 2.0 * math.pi * rng.random()
    return (center[0] + r * math.cos(angle), center[1] + r * math.sin(angle))


def _climb_first(position: Point, altitude: float, radius: float) -> list[Point]:
    """A vertical leg up to ``altitude`` when the vehicle is below it (never fly low
    sideways, e.g. from a verification hover)."""
    if position[2] < altitude - radius:
        return [(position[0], position[1], altitude)]
    return []


def _battery_problem(vehicle: VehiclePort, reserve: float | None) -> str | None:
    """Why searching must stop: the battery reached the reserve (searching only goes on
    while the battery allows; the reserve is kept for landing)."""
    if reserve is not None and battery_below(vehicle, reserve):
        return f"battery at or below the reserve {reserve:g} %: no further search"
    return None


class LandingSiteSearch(RouteAction):
    """Fly a rectangle of waypoints at ``altitude`` so that the detector sees new ground.

    The centre is PATTERN_CENTER when ``use_pattern_center`` (set by
    :class:`GetNextPatternCenterWP`), else where the vehicle is on entry. A vehicle below
    ``altitude`` climbs vertically first. Each pattern started adds one to SEARCH_PATTERNS.
    With ``battery_reserve`` set, no search flies (or goes on) at or below that level.
    With an operating ``area``, the rectangle is shrunk about its centre
    (:data:`PATTERN_SCALES`) until it and the leg to its first corner lie inside.

    * SUCCESS: the LSM holds a site (checked every tick; the rest of the pattern is dropped)
    * FAILURE: the pattern was flown and the LSM is still empty, the battery reached the
      reserve, no pattern fits in the area, or a goto denied / unanswered
    * RUNNING: flying the pattern
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        lsm: LandingSiteManager,
        *,
        size: tuple[float, float],
        altitude: float,
        use_pattern_center: bool = False,
        battery_reserve: float | None = None,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
        pattern_center_key: str = keys.PATTERN_CENTER,
        area: OperatingArea | None = None,
    ) -> None:
        super().__init__(
            name,
            vehicle,
            clock,
            acceptance_radius=acceptance_radius,
            command_timeout=command_timeout,
            phase="search",
        )
        self.lsm = lsm
        self.area = area
        self.size = (float(size[0]), float(size[1]))
        self.altitude = float(altitude)
        self.use_pattern_center = use_pattern_center
        self.battery_reserve = battery_reserve
        self.pattern_center_key = pattern_center_key
        self.blackboard.register_key(key=keys.SEARCH_PATTERNS, access=Access.WRITE)
        self.blackboard.register_key(key=pattern_center_key, access=Access.READ)

    def check(self, position: Point) -> Status | None:
        if len(self.lsm):
            self.feedback_message = "site found"
            return Status.SUCCESS
        problem = _battery_problem(self.vehicle, self.battery_reserve)
        if problem is not None:
            return self.fail(problem)
        return None

    def plan_route(self, position: Point) -> list[Point] | str:
        self.blackboard.set(keys.SEARCH_PATTERNS, self.blackboard.get(keys.SEARCH_PATTERNS) + 1)
        center = self.blackboard.get(self.pattern_center_key) if self.use_pattern_center else None
        if center is None:
            center = (position[0], position[1])
        climb = _climb_first(position, self.altitude, self.acceptance_radius)
        if self.area is None:
            return climb + rectangle_pattern(center, self.size, self.altitude,
                                             start_near=position[:2])
        for scale in PATTERN_SCALES:
            size = (self.size[0] * scale, self.size[1] * scale)
            corners = rectangle_pattern(center, size, self.altitude, start_near=position[:2])
            if self.area.route_inside([position, *corners]):
                return climb + corners
        return (f"no search pattern around ({center[0]:.1f}, {center[1]:.1f}) fits in the "
                "geofence")

    def route_done(self) -> Status:
        return self.fail("pattern flown, no landing site found")


class GetNextPatternCenterWP(RouteAction):
    """Draw a new search-pattern centre uniformly within ``radius`` of ``anchor`` (the last
    mission waypoint) with the seeded generator, write it to PATTERN_CENTER, fly there at
    ``altitude`` (climbing vertically first when below it). Meant to run under py_trees'
    ``Retry`` with :class:`LandingSiteSearch`: every entry draws a new centre. With
    ``battery_reserve`` set, it does not start (or go on) at or below that level, which ends
    the retries "while the battery allows" (thesis 3.3.1). With an operating ``area`` the
    centre is drawn again (same generator, at most :data:`CENTRE_DRAWS` times) until it
    lies inside and the straight leg to it from the vehicle does too.

    * SUCCESS: at the new centre
    * FAILURE: the battery reached the reserve, no centre inside the area was drawn, or a
      goto denied or unanswered
    * RUNNING: flying
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        rng: np.random.Generator,
        *,
        anchor: tuple[float, float],
        radius: float,
        altitude: float,
        battery_reserve: float | None = None,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
        pattern_center_key: str = keys.PATTERN_CENTER,
        area: OperatingArea | None = None,
    ) -> None:
        super().__init__(
            name,
            vehicle,
            clock,
            acceptance_radius=acceptance_radius,
            command_timeout=command_timeout,
            phase="search",
        )
        self.rng = rng
        self.area = area
        self.anchor = (float(anchor[0]), float(anchor[1]))
        self.radius = float(radius)
        self.altitude = float(altitude)
        self.battery_reserve = battery_reserve
        self.center: tuple[float, float] | None = None
        self.pattern_center_key = pattern_center_key
        self.blackboard.register_key(key=pattern_center_key, access=Access.WRITE)

    def initialise(self) -> None:
        super().initialise()
        if self.area is None:
            self.center = random_point_in_disc(self.rng, self.anchor, self.radius)
        else:
            self.center = self._centre_inside(self.area)
        if self.center is not None:
            self.blackboard.set(self.pattern_center_key, self.center)

    def _centre_inside(self, area: OperatingArea) -> tuple[float, float] | None:
        position = self.vehicle.state.position
        for _ in range(CENTRE_DRAWS):
            center = random_point_in_disc(self.rng, self.anchor, self.radius)
            if position is None:
                if area.contains_point(*center):
                    return center
            elif area.leg_inside(position, center):
                return center
        return None

    def check(self, position: Point) -> Status | None:
        problem = _battery_problem(self.vehicle, self.battery_reserve)
        return None if problem is None else self.fail(problem)

    def plan_route(self, position: Point) -> list[Point] | str:
        if self.center is None:
            return (f"no pattern centre inside the geofence within {self.radius:g} m of "
                    f"({self.anchor[0]:.1f}, {self.anchor[1]:.1f}) in {CENTRE_DRAWS} draws")
        climb = _climb_first(position, self.altitude, self.acceptance_radius)
        return climb + [(self.center[0], self.center[1], self.altitude)]
