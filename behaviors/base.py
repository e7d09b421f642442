"""Plumbing shared by the mission behaviours: phase reporting, failure reasons, command
tracking against the injected clock, and waypoint routes flown leg by leg."""

from __future__ import annotations

import math
from collections.abc import Sequence

import py_trees
from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.ports import Clock, CommandHandle, CommandStatus, VehiclePort
from behaviors.ticking import QuietBehaviour

Point = tuple[float, float, float]


def horizontal_distance(a: Sequence[float], b: Sequence[float]) -> float:
    """Distance in the x-y plane between two ENU points, m."""
    return math.hypot(a[0] - b[0], a[1] - b[1])


def reached(position: Sequence[float], target: Sequence[float], radius: float) -> bool:
    """True when ``position`` is within ``radius`` of ``target`` horizontally and vertically."""
    return (
        horizontal_distance(position, target) <= radius and abs(position[2] - target[2]) <= radius
    )


class MissionBehaviour(QuietBehaviour):
    """A behaviour that reports the mission phase and why it failed.

    On entry it writes ``phase`` (when given) to :data:`behaviors.blackboard.PHASE`;
    :meth:`fail` puts a reason in the feedback message and in
    :data:`behaviors.blackboard.FAILURE_REASON`.
    """

    def __init__(self, name: str, *, phase: str | None = None) -> None:
        super().__init__(name=name)
        if phase is not None and phase not in keys.PHASES:
            raise ValueError(f"unknown phase {phase!r}; expected one of {keys.PHASES}")
        self.phase = phase
        self.blackboard = self.attach_blackboard_client(name)
        self.blackboard.register_key(key=keys.PHASE, access=Access.WRITE)
        self.blackboard.register_key(key=keys.FAILURE_REASON, access=Access.WRITE)

    def initialise(self) -> None:
        self.feedback_message = ""
        if self.phase is not None:
            self.blackboard.set(keys.PHASE, self.phase)

    def peek(self, key: str) -> object:
        """``self.blackboard.get(key)`` for a key registered unremapped, read straight from
        the storage when no activity stream records reads (the client's access checks cost
        more than the condition checked on every tick)."""
        if (py_trees.blackboard.Blackboard.activity_stream is None
                and self.blackboard.remappings.get(key) == key and "." not in key):
            return py_trees.blackboard.Blackboard.storage[key]
        return self.blackboard.get(key)

    def fail(self, reason: str) -> Status:
        """Record ``reason`` (feedback message and FAILURE_REASON) and return FAILURE."""
        self.feedback_message = reason
        self.blackboard.set(keys.FAILURE_REASON, f"{self.name}: {reason}")
        return Status.FAILURE


class VehicleAction(MissionBehaviour):
    """A mission behaviour that commands the vehicle and watches the command's answer.

    The latest command's handle is checked on every :meth:`command_problem` call: DENIED or
    TIMED_OUT, or still PENDING ``command_timeout`` clock seconds after it was issued, is a
    problem described in words (with the autopilot's reason when it gave one).
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        *,
        command_timeout: float = 5.0,
        phase: str | None = None,
    ) -> None:
        super().__init__(name, phase=phase)
        self.vehicle = vehicle
        self.clock = clock
        self.command_timeout = float(command_timeout)
        self.handle: CommandHandle | None = None
        self.issued_at = 0.0

    def initialise(self) -> None:
        super().initialise()
        self.handle = None

    def command(self, handle: CommandHandle) -> CommandHandle:
        """Track ``handle`` (the answer to a command just sent) from now on."""
        self.handle = handle
        self.issued_at = self.clock.now()
        return handle

    def command_problem(self) -> str | None:
        """What went wrong with the latest command, or None while all is well."""
        handle = self.handle
        if handle is None:
            return None
        status = handle.status
        if status is CommandStatus.DENIED or status is CommandStatus.TIMED_OUT:
            reason = handle.reason or "no reason given"
            verb = "denied" if status is CommandStatus.DENIED else "timed out"
            return f"{handle.name} {verb}: {reason}"
        if (
            status is CommandStatus.PENDING
            and self.clock.now() - self.issued_at > self.command_timeout
        ):
            return f"{handle.name}: no answer within {self.command_timeout:g} s"
        return None


class RouteAction(VehicleAction):
    """Fly a list of ENU waypoints (legs) one after the other with ``vehicle.goto``.

    Subclasses say where to go in :meth:`plan_route`, called once the vehicle position is
    known on entry; a leg counts as flown inside ``acceptance_radius`` (horizontal and
    vertical), and legs already reached are skipped in the same tick.

    * SUCCESS: every leg flown (subclasses may end earlier, see :meth:`check`)
    * FAILURE: no route (the reason of :meth:`plan_route`), or a goto denied / unanswered
    * RUNNING: flying
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        *,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
        phase: str | None = None,
    ) -> None:
        super().__init__(name, vehicle, clock, command_timeout=command_timeout, phase=phase)
        self.acceptance_radius = float(acceptance_radius)
        self.legs: list[Point] | None = None
        self.leg = 0
        self.leg_commanded = False

    def plan_route(self, position: Point) -> list[Point] | str:
        """The legs to fly from ``position``, or a reason why there is no route."""
        raise NotImplementedError

    def check(self, position: Point) -> Status | None:
        """Hook run every tick before flying; a status ends the behaviour with it."""
        return None

    def route_done(self) -> Status:
        """Status once every leg is flown."""
        self.feedback_message = "arrived"
        return Status.SUCCESS

    def initialise(self) -> None:
        super().initialise()
        self.legs = None
        self.leg = 0
        self.leg_commanded = False

    def update(self) -> Status:
        position = self.vehicle.state.position
        if position is None:
            self.feedback_message = "waiting for the vehicle position"
            return Status.RUNNING
        early = self.check(position)
        if early is not None:
            return early
        if self.legs is None:
            route = self.plan_route(position)
            if isinstance(route, str):
                return self.fail(route)
            self.legs = route
        problem = self.command_problem()
        if problem is not None:
            return self.fail(problem)
        legs = self.legs
        while self.leg < len(legs) and reached(position, legs[self.leg], self.acceptance_radius):
            self.leg += 1
            self.leg_commanded = False
        if self.leg == len(legs):
            return self.route_done()
        target = legs[self.leg]
        if not self.leg_commanded:
            self.command(self.vehicle.goto(*target))
            self.leg_commanded = True
        self.feedback_later("leg {}/{} to ({:.1f}, {:.1f}, {:.1f}), {:.1f} m to go",
                            self.leg + 1, len(legs), target[0], target[1], target[2],
                            horizontal_distance(position, target))
        return Status.RUNNING
