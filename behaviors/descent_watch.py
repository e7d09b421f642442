"""The descent to the verification altitude under the optical-flow watch of seed 004 (Lee et
al. 2019, sections 3.3 and 4.2): the thesis's blind descent (ChangeAltitudeLS), stopped
when the descent camera's flow flags an obstacle, a step away from it, and on again; and
the landing from there (Land) under the same watch and the rangefinder's, aborted by a
climb when an obstacle is flagged or something enters the column. A site the watch backs
away from is banned like one that fails verification."""

from __future__ import annotations

import math
from collections import Counter, deque
from typing import TYPE_CHECKING

from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.base import (
    MissionBehaviour,
    Point,
    VehicleAction,
    horizontal_distance,
    reached,
)
from behaviors.flight import Land
from behaviors.ports import (
    Clock,
    CommandStatus,
    LandedState,
    ObstacleSighting,
    ObstacleWatch,
    VehiclePort,
    VehicleState,
)

if TYPE_CHECKING:
    from lsm import LandingSiteManager


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


class ColumnWatch:
    """The downward rangefinder's watch over the column below a vehicle descending
    straight: the ground it reads (vehicle z less the range) stays put, so ground that rises
    more than ``margin`` m above the lowest read in the last ``window`` s is something that
    entered the column (a car driving under the vehicle). The window follows slow drift of
    the vehicle's height estimate; ``reference`` (e.g. the chosen site's height) adds a
    floor known from elsewhere. The range and the position arrive in different messages, so
    while the vehicle climbs or descends the margin grows by ``lag`` s of its vertical speed;
    and the beam tilts with the vehicle (it reads farther than straight down): readings taken
    while it speeds up or brakes sideways by more than ``max_tilt_acceleration`` m/s^2 are
    left out."""

    def __init__(self, margin: float = 0.5, window: float = 3.0, lag: float = 0.5,
                 max_tilt_acceleration: float = 0.5) -> None:
        self.margin = float(margin)
        self.window = float(window)
        self.lag = float(lag)
        self.max_tilt_acceleration = float(max_tilt_acceleration)
        self.readings: deque[tuple[float, float]] = deque()
        self._velocity: tuple[float, float, float] | None = None  # t, vx, vy

    def reset(self) -> None:
        """Forget the ground read so far (the column moved)."""
        self.readings.clear()
        self._velocity = None

    def _tilting(self, state: VehicleState, now: float) -> bool:
        """Whether the vehicle speeds up or brakes sideways (and so tilts) now."""
        vx, vy, _ = state.velocity
        last, self._velocity = self._velocity, (now, vx, vy)
        if last is None or now <= last[0]:
            return True  # not known yet
        accel = math.hypot(vx - last[1], vy - last[2]) / (now - last[0])
        return accel > self.max_tilt_acceleration

    def intrusion(self, state: VehicleState, now: float,
                  reference: float = math.inf) -> str | None:
        """What entered the column, in words, or None (also without a range or position)."""
        rf, position = state.rangefinder_agl, state.position
        if self._tilting(state, now) or rf is None or position is None or not math.isfinite(rf):
            return None
        below = position[2] - rf  # ENU z of what the rangefinder sees
        readings = self.readings
        while readings and readings[0][0] < now - self.window:
            readings.popleft()
        floor = min([reference, below, *(g for _, g in readings)])
        readings.append((now, below))
        if below - floor > self.margin + self.lag * abs(state.velocity[2]):
            return (f"something {below - floor:.1f} m high entered the column below "
                    f"(rangefinder {rf:.1f} m at {position[2]:.1f} m)")
        return None


class WatchAborts:
    """How often the watch backed away from each site (by LSM id), shared by a tree's
    watched nodes: the site the watch keeps backing away from is banned (``lsm.ban``, the
    thesis's ban of a site that fails its check: later detections within the LSM's
    ``ban_radius`` are rejected), so the tree does not come back to a blocked column."""

    def __init__(self) -> None:
        self.counts: Counter[int] = Counter()

    def backed_away(self, lsm: LandingSiteManager | None, site, ban_after: int) -> str:
        """Count a retreat from ``site`` (a LandingSite, or None: nothing to count) and ban
        it once it has ``ban_after`` (0: never); returns what became of the site, in words."""
        if site is None or lsm is None:
            return ""
        self.counts[site.id] += 1
        n = self.counts[site.id]
        if ban_after <= 0 or n < ban_after:
            left = "" if ban_after <= 0 else f", banned after {ban_after}"
            return f"site {site.id} kept ({n} retreat(s){left})"
        banned = lsm.ban(site.id)
        return f"site {site.id} banned" if banned else f"site {site.id} no longer retained"


def record_ban(behaviour: MissionBehaviour, outcome: str) -> None:
    """Count a ban in :data:`behaviors.blackboard.BANNED_SITES` (the flight report's)."""
    if outcome.endswith("banned"):
        count = behaviour.blackboard.get(keys.BANNED_SITES)
        behaviour.blackboard.set(keys.BANNED_SITES, count + 1)


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
    the landing try ends and the tree chooses again (re-plans); given the ``lsm``, the
    retreat counts in ``aborts`` and the site is banned after ``ban_after`` of them (see
    :class:`WatchAborts`). Given ``column_margin``, the rangefinder watches the column too
    (:class:`ColumnWatch`, while descending straight): something entering it (a car driving
    under the vehicle: the site is on its way) makes the vehicle climb back and fail alike.

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
        lsm: LandingSiteManager | None = None,
        aborts: WatchAborts | None = None,
        ban_after: int = 1,
        column_margin: float | None = None,
    ) -> None:
        super().__init__(name, vehicle, clock, command_timeout=command_timeout, phase=phase)
        self.height = float(height)
        self.watch = watch
        self.column = None if column_margin is None else ColumnWatch(column_margin)
        self.lsm = lsm
        self.aborts = aborts if aborts is not None else WatchAborts()
        self.ban_after = int(ban_after)
        self.step = float(step)
        self.max_offset = float(max_offset)
        self.settle = float(settle)
        self.acceptance_radius = float(acceptance_radius)
        self.still_radius = min(0.3, self.acceptance_radius)  # m, over the new column
        self.still_speed = 0.3  # m/s sideways at most when the descent resumes
        self.blackboard.register_key(key=keys.LANDING_SITE, access=Access.READ)
        self.blackboard.register_key(key=keys.BANNED_SITES, access=Access.WRITE)
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
        if self.column is not None:
            self.column.reset()

    def _climb_back(self, reason: str) -> None:
        """Give up this column: back up to where the descent began, then fail."""
        self.watch.watch(False)
        self.abort_reason = f"{reason}; climbed back to {self.start_z:.1f} m"
        self._goto((self.site.x + self.offset[0], self.site.y + self.offset[1], self.start_z))
        self.mode = "climb"

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
            self._climb_back(
                f"obstacle ({where}) beside the descent at {position[2]:.1f} m and no room to "
                f"step away within {self.max_offset:g} m of the site"
            )
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
            if not arrived:
                return Status.RUNNING
            outcome = self.aborts.backed_away(self.lsm, self.site, self.ban_after)
            record_ban(self, outcome)
            return self.fail(self.abort_reason + (f" ({outcome})" if outcome else ""))
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
        if self.column is not None:
            intrusion = self.column.intrusion(self.vehicle.state, self.clock.now())
            if intrusion is not None:
                self._climb_back(f"{intrusion} during the descent")
                return Status.RUNNING
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


class WatchedLand(Land):
    """Land where the vehicle is (like :class:`behaviors.flight.Land`) while the descent
    camera's optical flow (``watch``) and the downward rangefinder watch the last metres.

    The landing is aborted when a sighting flags an obstacle (from ``settle`` s after the
    landing began) or when something rises into the column below (:class:`ColumnWatch`):
    the rangefinder reads the ground more than ``column_margin`` m higher than the lowest it
    read in the last 3 s (or than the chosen site, when the vehicle is within 1 m of its
    column); a car or a person walking under the vehicle. Then the vehicle leaves LAND for
    a goto (GUIDED or OFFBOARD; ArduPilot and PX4 accept that change out of LAND) to
    ``height`` m above the site (above the lowest ground read when no site is chosen), at
    least where it is, and once there the behaviour fails, so the tree goes on as after a
    failed verification: the site is counted as backed away from (``aborts``) and banned
    after ``ban_after`` retreats (0: never), and the next try chooses again. The watch
    stops at touchdown.

    * SUCCESS: landed and disarmed (as Land)
    * FAILURE: the land, goto or disarm command denied or unanswered; the landing aborted
      (after the climb)
    * RUNNING: landing, or climbing back after an abort
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        watch: ObstacleWatch,
        *,
        height: float = 2.5,
        lsm: LandingSiteManager | None = None,
        aborts: WatchAborts | None = None,
        ban_after: int = 1,
        settle: float = 1.0,
        column_margin: float = 0.5,
        acceptance_radius: float = 1.0,
        phase: str = "land",
        outcome_hint: str | None = None,
        command_timeout: float = 5.0,
    ) -> None:
        super().__init__(name, vehicle, clock, phase=phase, outcome_hint=outcome_hint,
                         command_timeout=command_timeout)
        self.watch = watch
        self.height = float(height)
        self.lsm = lsm
        self.aborts = aborts if aborts is not None else WatchAborts()
        self.ban_after = int(ban_after)
        self.settle = float(settle)
        self.column_margin = float(column_margin)
        self.acceptance_radius = float(acceptance_radius)
        self.blackboard.register_key(key=keys.LANDING_SITE, access=Access.READ)
        self.blackboard.register_key(key=keys.BANNED_SITES, access=Access.WRITE)
        self.column = ColumnWatch(column_margin)
        self.site = None
        self.mode = "land"  # land | climb
        self.target: Point | None = None
        self.started = 0.0
        self.abort_reason = ""
        self.watching = False

    def initialise(self) -> None:
        super().initialise()  # sends the land command
        self.site = self.blackboard.get(keys.LANDING_SITE)
        self.mode = "land"
        self.target = None
        self.started = self.clock.now()
        self.column.reset()
        self.abort_reason = ""
        self.watching = True
        self.watch.watch(True)

    def terminate(self, new_status: Status) -> None:
        self.watch.watch(False)

    def _threat(self, state) -> str | None:
        sighting = self.watch.latest()
        if (sighting is not None and sighting.obstacle
                and sighting.time >= self.started + self.settle):
            where = ", ".join(sighting.directions) or "around"
            return f"obstacle ({where}) beside the landing"
        site = self.site
        # The chosen site's height is a floor too (a car parked on it from the start).
        reference = site.z if site is not None and state.position is not None and (
            horizontal_distance(state.position, site.position) <= 1.0) else math.inf
        return self.column.intrusion(state, self.clock.now(), reference)

    def _abort(self, position: Point, reason: str) -> None:
        self.watching = False
        self.watch.watch(False)
        lowest = min((g for _, g in self.column.readings), default=position[2])
        floor = self.site.z if self.site is not None else lowest
        self.target = (position[0], position[1], max(position[2], floor + self.height))
        self.command(self.vehicle.goto(*self.target))
        self.mode = "climb"
        self.abort_reason = f"{reason} at {position[2]:.1f} m; landing aborted"
        self.feedback_message = f"{self.abort_reason}, climbing to {self.target[2]:.1f} m"

    def update(self) -> Status:
        state = self.vehicle.state
        if self.mode == "climb":
            problem = self.command_problem()
            if problem is not None:
                return self.fail(problem)
            # Reached only counts once the autopilot follows the goto (it left LAND).
            if self.handle.status is CommandStatus.ACCEPTED and state.position is not None \
                    and reached(state.position, self.target, self.acceptance_radius):
                outcome = self.aborts.backed_away(self.lsm, self.site, self.ban_after)
                record_ban(self, outcome)
                return self.fail(f"{self.abort_reason}, climbed back to {self.target[2]:.1f} m"
                                 + (f" ({outcome})" if outcome else ""))
            return Status.RUNNING
        if not state.armed or state.landed_state is LandedState.ON_GROUND:
            if self.watching:
                self.watching = False
                self.watch.watch(False)  # touched down: nothing left to avoid
        # Watch once the autopilot is in LAND (the command accepted): a goto sent before
        # would be overtaken by the mode change still under way.
        elif (self.handle is not None and self.handle.status is CommandStatus.ACCEPTED
              and state.position is not None):
            reason = self._threat(state)
            if reason is not None:
                self._abort(state.position, reason)
                return Status.RUNNING
        return super().update()
