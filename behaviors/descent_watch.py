"""The descent to the verification altitude under the optical-flow watch of seed 004 (Lee et
al. 2019, sections 3.3 and 4.2): the thesis's blind descent (ChangeAltitudeLS), stopped
when the descent camera's flow flags an obstacle, a step away from it, and on again."""

from __future__ import annotations

import math

from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.base import Point, VehicleAction, horizontal_distance, reached
from behaviors.ports import Clock, ObstacleSighting, ObstacleWatch, VehiclePort


def away_in_enu(away: tuple[float, float], yaw: float) -> tuple[float, float]:
    """An image-axes direction (x right, y up) of a nadir camera on a vehicle with heading
    ``yaw`` (rad, ENU) as an ENU (east, north) direction: image right is the vehicle's right
    ``(sin yaw, -cos yaw)``, image up its nose ``(cos yaw, sin yaw)``."""
    ax, ay = away
    s, c = math.sin(yaw), math.cos(yaw)
    return (ax * s + ay * c, -ax * c + ay * s)


def step_within(
    offset: tuple[float, float], direction: tuple[float, float], step: float, max_offset: float
) -> float:
    """How far (m, 0..``step``) to move from ``offset`` along the unit ``direction`` without
    leaving the disc of radius ``max_offset`` around the site column."""
    ox, oy = offset
    dx, dy = direction
    # |o + t d|^2 = r^2, the larger root: how far along d before the rim.
    b = ox * dx + oy * dy
    c = ox * ox + oy * oy - max_offset * max_offset
    disc = b * b - c
    if disc < 0:
        return 0.0
    return max(0.0, min(step, -b + math.sqrt(disc)))


class WatchedDescent(VehicleAction):
    """Descend to ``height`` m above the chosen site (like
    :class:`behaviors.flight.ChangeAltitudeLS`) while the optical flow of the descent
    camera (``watch``) looks for obstacles around the column.

    When a sighting flags an obstacle, the descent stops where the vehicle is (a goto at its
    current altitude), the column moves up to ``step`` m away from the obstacle (the
    sighting's away vector turned into ENU with the camera's heading), at most
    ``max_offset`` m from the site in all, and once over the new column (within 0.3 m,
    moving sideways at under 0.3 m/s) the descent resumes there. Sightings from the step
    itself and from the first ``settle`` seconds after it are ignored (the watch is off
    while stepping: sideways flow is not a descent's). With no room left to step away, the
    vehicle climbs back to the altitude the descent began at and the behaviour fails, so
    the landing try ends and the tree chooses again (re-plans).

    The descent ends over the moved column: the verification hover and the centring over the
    verified site that follow bring the vehicle back over the site, low and slowly.

    * SUCCESS: at ``height`` above the site, over the (possibly moved) column
    * FAILURE: no site on the blackboard; a goto denied or unanswered; no room to step away
      (after the climb)
    * RUNNING: descending, stepping away, or climbing back
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        height: float,
        watch: ObstacleWatch,
        *,
        step: float = 1.5,
        max_offset: float = 3.0,
        settle: float = 1.0,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
        phase: str = "descend",
    ) -> None:
        super().__init__(name, vehicle, clock, command_timeout=command_timeout, phase=phase)
        self.height = float(height)
        self.watch = watch
        self.step = float(step)
        self.max_offset = float(max_offset)
        self.settle = float(settle)
        self.acceptance_radius = float(acceptance_radius)
        self.still_radius = min(0.3, self.acceptance_radius)  # m, over the new column
        self.still_speed = 0.3  # m/s sideways at most when the descent resumes
        self.blackboard.register_key(key=keys.LANDING_SITE, access=Access.READ)
        self._reset()

    def _reset(self) -> None:
        self.site = None
        self.offset = (0.0, 0.0)
        self.mode = "descend"  # descend | step | climb
        self.target: Point | None = None
        self.start_z = 0.0
        self.resumed_at = -math.inf
        self.last_sighting = -math.inf
        self.steps = 0
        self.abort_reason = ""

    def initialise(self) -> None:
        super().initialise()
        self._reset()

    def terminate(self, new_status: Status) -> None:
        self.watch.watch(False)

    def _goto(self, target: Point) -> None:
        self.target = target
        self.command(self.vehicle.goto(*target))

    def _descend(self) -> None:
        site = self.site
        self._goto((site.x + self.offset[0], site.y + self.offset[1], site.z + self.height))
        self.mode = "descend"
        self.resumed_at = self.clock.now()
        self.watch.watch(True)

    def _avoid(self, position: Point, sighting: ObstacleSighting) -> None:
        ex, ey = away_in_enu(sighting.away, sighting.yaw)
        norm = math.hypot(ex, ey)
        if norm < 1e-9:
            return  # obstacles on opposite sides cancel: no direction to take
        direction = (ex / norm, ey / norm)
        where = ", ".join(sighting.directions) or "around"
        self.watch.watch(False)
        move = step_within(self.offset, direction, self.step, self.max_offset)
        if move < 0.25 * self.step:
            self.abort_reason = (
                f"obstacle ({where}) beside the descent at {position[2]:.1f} m and no room to "
                f"step away within {self.max_offset:g} m of the site; climbed back to "
                f"{self.start_z:.1f} m"
            )
            self._goto((self.site.x + self.offset[0], self.site.y + self.offset[1],
                        self.start_z))
            self.mode = "climb"
            return
        self.offset = (self.offset[0] + move * direction[0], self.offset[1] + move * direction[1])
        self.steps += 1
        self._goto((self.site.x + self.offset[0], self.site.y + self.offset[1], position[2]))
        self.mode = "step"
        self.feedback_message = (
            f"obstacle ({where}): stepping {move:.1f} m away at {position[2]:.1f} m, "
            f"{math.hypot(*self.offset):.1f} m from the site column"
        )

    def update(self) -> Status:
        position = self.vehicle.state.position
        if position is None:
            self.feedback_message = "waiting for the vehicle position"
            return Status.RUNNING
        if self.site is None:
            site = self.blackboard.get(keys.LANDING_SITE)
            if site is None:
                return self.fail("no landing site chosen")
            self.site = site
            self.start_z = position[2]
            self._descend()
        problem = self.command_problem()
        if problem is not None:
            return self.fail(problem)
        arrived = reached(position, self.target, self.acceptance_radius)
        if self.mode == "climb":
            return self.fail(self.abort_reason) if arrived else Status.RUNNING
        if self.mode == "step":
            # Resume once over the new column and nearly still: sideways motion would
            # read as flow of its own.
            vx, vy, _ = self.vehicle.state.velocity
            if (horizontal_distance(position, self.target) <= self.still_radius
                    and math.hypot(vx, vy) <= self.still_speed):
                self._descend()
            return Status.RUNNING
        if arrived:
            moved = f", {self.steps} step(s) away from obstacles" if self.steps else ""
            self.feedback_message = f"at {self.height:g} m above the site{moved}"
            return Status.SUCCESS
        sighting = self.watch.latest()
        if (
            sighting is not None
            and sighting.obstacle
            and sighting.time > self.last_sighting
            and sighting.time >= self.resumed_at + self.settle
        ):
            self.last_sighting = sighting.time
            self._avoid(position, sighting)
            return Status.RUNNING
        self.feedback_message = f"descending, {position[2] - self.target[2]:.1f} m to go"
        return Status.RUNNING
