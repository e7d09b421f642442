"""Test doubles for the behaviour tests: a kinematic vehicle satisfying VehiclePort, a
scripted landing-site detector, and a lockstep loop like the runner's."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import py_trees

from autonomy.clock import SimClock
from behaviors.ports import CommandStatus, LandedState, VehicleState
from lsm import LandingSiteManager, SiteObservation


@dataclass
class FakeHandle:
    """A command handle whose status the fake sets at once."""

    name: str
    status: CommandStatus = CommandStatus.ACCEPTED
    reason: str = ""


class FakeVehicle:
    """A point-mass multicopter that flies straight at its target each step.

    Horizontal speed and climb rate are limited; LAND descends to the ground height and
    disarms on touchdown. ``deny`` maps a command name ("takeoff", "goto", "land", ...) to
    the reason the fake autopilot gives when refusing it; ``silent`` names commands that
    are never answered (PENDING forever). ``battery``, ``gps_fix`` and
    ``position_estimate`` can be set by the test at any time.
    """

    def __init__(
        self,
        clock: SimClock,
        *,
        speed: float = 12.0,
        climb_rate: float = 6.0,
        ground: Callable[[float, float], float] = lambda x, y: 0.0,
        battery: float = 100.0,
        prearm_ok: bool = True,
        deny: dict[str, str] | None = None,
        silent: set[str] | None = None,
    ) -> None:
        self.clock = clock
        self.speed = speed
        self.climb_rate = climb_rate
        self.ground = ground
        self.battery = battery
        self.prearm_ok = prearm_ok
        self.deny = dict(deny or {})
        self.silent = set(silent or ())
        self.position = (0.0, 0.0, ground(0.0, 0.0))
        self.target: tuple[float, float, float] | None = None
        self.armed = False
        self.mode = "STABILIZE"
        self.landing = False
        self.commands: list[tuple[str, tuple]] = []
        self.status_text = ""
        self.gps_fix = 3
        self.position_estimate = True

    # ------------------------------------------------------------------ VehiclePort
    @property
    def state(self) -> VehicleState:
        x, y, z = self.position
        on_ground = z <= self.ground(x, y) + 0.05
        if on_ground and (not self.armed or self.target is None or self.target[2] <= z):
            landed = LandedState.ON_GROUND
        elif self.landing:
            landed = LandedState.LANDING
        else:
            landed = LandedState.IN_AIR
        return VehicleState(
            time=self.clock.now(),
            position=self.position,
            armed=self.armed,
            mode=self.mode,
            landed_state=landed,
            battery_percent=self.battery,
            gps_fix=self.gps_fix,
            heartbeat_age=0.0,
            link_lost=False,
            prearm_ok=self.prearm_ok,
            position_estimate=self.position_estimate,
            autopilot="ardupilot",
            last_status_text=self.status_text,
        )

    def _answer(self, name: str, *args) -> FakeHandle | None:
        self.commands.append((name, args))
        if name in self.deny:
            self.status_text = self.deny[name]
            return FakeHandle(name, CommandStatus.DENIED, self.deny[name])
        if name in self.silent:
            return FakeHandle(name, CommandStatus.PENDING)
        return None

    def arm(self) -> FakeHandle:
        refused = self._answer("arm")
        if refused:
            return refused
        if not self.prearm_ok:
            return FakeHandle("arm", CommandStatus.DENIED, "PreArm: checks failing")
        self.armed = True
        return FakeHandle("arm")

    def disarm(self) -> FakeHandle:
        refused = self._answer("disarm")
        if refused:
            return refused
        self.armed = False
        return FakeHandle("disarm")

    def set_mode(self, mode: str) -> FakeHandle:
        refused = self._answer("set_mode", mode)
        if refused:
            return refused
        self.mode = mode
        return FakeHandle("set_mode")

    def takeoff(self, altitude: float) -> FakeHandle:
        refused = self._answer("takeoff", altitude)
        if refused:
            return refused
        if not self.prearm_ok:
            return FakeHandle("takeoff", CommandStatus.DENIED, "PreArm: checks failing")
        x, y, _ = self.position
        self.armed, self.mode, self.landing = True, "GUIDED", False
        self.target = (x, y, altitude)
        return FakeHandle("takeoff")

    def goto(self, x: float, y: float, z: float) -> FakeHandle:
        refused = self._answer("goto", x, y, z)
        if refused:
            return refused
        if not self.armed:
            return FakeHandle("goto", CommandStatus.DENIED, "not armed")
        self.mode, self.landing = "GUIDED", False
        self.target = (x, y, z)
        return FakeHandle("goto")

    def follow(self, x: float, y: float, z: float, vx: float, vy: float, vz: float):
        refused = self._answer("follow", x, y, z, vx, vy, vz)
        if refused:
            return refused
        if not self.armed:
            return FakeHandle("follow", CommandStatus.DENIED, "not armed")
        self.mode, self.landing = "GUIDED", False
        self.target = (x, y, z)
        return FakeHandle("follow")

    def set_velocity(self, vx: float, vy: float, vz: float) -> FakeHandle:
        return self._answer("set_velocity", vx, vy, vz) or FakeHandle("set_velocity")

    def hold(self) -> FakeHandle:
        refused = self._answer("hold")
        if refused:
            return refused
        self.target = self.position
        return FakeHandle("hold")

    def upload_fence(self, polygon, max_altitude=None, exclusions=()) -> FakeHandle:
        zones = (tuple(tuple(zone) for zone in exclusions),) if exclusions else ()
        return self._answer("upload_fence", tuple(polygon), max_altitude, *zones) or FakeHandle(
            "upload_fence")

    def land(self) -> FakeHandle:
        refused = self._answer("land")
        if refused:
            return refused
        self.mode, self.landing = "LAND", True
        return FakeHandle("land")

    # ------------------------------------------------------------------ simulation
    def step(self, dt: float) -> None:
        """Move for ``dt`` seconds toward the target (or down, when landing)."""
        if not self.armed:
            return
        x, y, z = self.position
        if self.landing:
            tx, ty, tz = x, y, self.ground(x, y)
        elif self.target is None:
            return
        else:
            tx, ty, tz = self.target
        dx, dy = tx - x, ty - y
        horizontal = math.hypot(dx, dy)
        step = min(horizontal, self.speed * dt)
        if horizontal > 0:
            x, y = x + dx / horizontal * step, y + dy / horizontal * step
        dz = tz - z
        z += math.copysign(min(abs(dz), self.climb_rate * dt), dz)
        z = max(z, self.ground(x, y))
        self.position = (x, y, z)
        if self.landing and z <= self.ground(x, y) + 0.05:
            self.armed, self.landing, self.target = False, False, None

    def gotos(self) -> list[tuple[float, float, float]]:
        """Targets of every goto the fake accepted or refused, in order."""
        return [args for name, args in self.commands if name == "goto"]


@dataclass
class ScriptedSite:
    """A landing site the scripted detector reports when it is in the camera footprint.

    ``fails_verification``: the site is never re-detected from below ``low_altitude`` (a
    false positive from altitude).
    """

    x: float
    y: float
    z: float = 0.0
    roughness: float = 0.1
    uncertainty: float = 0.2
    size: float = 5.0
    obstacle_altitude: float = 5.0
    fails_verification: bool = False
    high_offset: tuple[float, float] = (0.0, 0.0)  # position error of looks from up high


@dataclass
class ScriptedDetector:
    """Reports every scripted site inside a nadir camera footprint of radius
    ``footprint * altitude above the site`` (at least ``min_radius``)."""

    sites: list[ScriptedSite]
    footprint: float = 0.3
    min_radius: float = 1.0
    low_altitude: float = 10.0
    reports: int = field(default=0)

    def observe(self, position: tuple[float, float, float], now: float) -> list[SiteObservation]:
        out = []
        for site in self.sites:
            altitude = position[2] - site.z
            if altitude < 0.5:
                continue
            radius = max(self.footprint * altitude, self.min_radius)
            if math.hypot(position[0] - site.x, position[1] - site.y) > radius:
                continue
            if site.fails_verification and altitude < self.low_altitude:
                continue
            dx, dy = site.high_offset if altitude >= self.low_altitude else (0.0, 0.0)
            out.append(
                SiteObservation(
                    x=site.x + dx,
                    y=site.y + dy,
                    z=site.z,
                    roughness=site.roughness,
                    uncertainty=site.uncertainty,
                    size=site.size,
                    obstacle_altitude=site.obstacle_altitude,
                    observation_altitude=altitude,
                    timestamp=now,
                    source="scripted",
                )
            )
        self.reports += len(out)
        return out


@dataclass
class Flight:
    """What a lockstep run left behind."""

    status: py_trees.common.Status
    ticks: int
    time: float
    track: list[tuple[float, float, float]]


def fly(
    tree: py_trees.trees.BehaviourTree,
    vehicle: FakeVehicle,
    clock: SimClock,
    lsm: LandingSiteManager,
    detector: ScriptedDetector | None = None,
    *,
    dt: float = 0.1,
    perception_every: int = 5,
    max_time: float = 4000.0,
    on_tick: Callable[[int], None] | None = None,
) -> Flight:
    """Run the mission in lockstep like the runner: advance time, move the vehicle, tell
    the LSM where the drone is, feed it detections (every ``perception_every`` ticks), tick.
    Stops when the root is no longer RUNNING or after ``max_time`` clock seconds."""
    track = []
    ticks = 0
    while clock.now() < max_time:
        clock.advance(dt)
        vehicle.step(dt)
        position = vehicle.position
        track.append(position)
        lsm.set_drone_position(position)
        if detector is not None and ticks % perception_every == 0:
            for observation in detector.observe(position, clock.now()):
                lsm.submit(observation)
            lsm.process_pending()
        if on_tick is not None:
            on_tick(ticks)
        tree.tick()
        ticks += 1
        if tree.root.status != py_trees.common.Status.RUNNING:
            break
    return Flight(tree.root.status, ticks, clock.now(), track)
