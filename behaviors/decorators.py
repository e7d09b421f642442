"""Decorators of the mission tree: a timeout on the injected clock (never the wall clock)
and a retry bounded by the battery."""

from __future__ import annotations

import py_trees
from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.failsafe import battery_leaves_room
from behaviors.ports import Clock, VehiclePort
from behaviors.ticking import QuietDecorator, Retry


class ClockTimeout(QuietDecorator):
    """Run a child for at most ``duration`` seconds of the injected clock.

    Used instead of py_trees' own timeout decorator, which reads the wall clock: the
    deadline is set when the decorator is entered, from ``clock.now()``.

    * SUCCESS / FAILURE: the child finished with it before the deadline
    * RUNNING: the child is running and the deadline has not passed
    * FAILURE: the deadline passed while the child was running; the child is stopped
      (INVALID), and the reason ("<child>: timed out after <d> s (<child's feedback>)") goes to
      the feedback message and :data:`behaviors.blackboard.FAILURE_REASON`

    Args:
        name: the decorator name
        child: the child behaviour or subtree
        clock: the injected clock
        duration: clock seconds allowed, > 0
    """

    def __init__(
        self, name: str, child: py_trees.behaviour.Behaviour, clock: Clock, duration: float
    ) -> None:
        if not duration > 0:
            raise ValueError(f"duration must be > 0 s, got {duration}")
        super().__init__(name=name, child=child)
        self.clock = clock
        self.duration = float(duration)
        self.deadline = float("inf")
        self.blackboard = self.attach_blackboard_client(self.name)
        self.blackboard.register_key(key=keys.FAILURE_REASON, access=Access.WRITE)

    def initialise(self) -> None:
        """Start the countdown."""
        self.deadline = self.clock.now() + self.duration
        self.feedback_message = ""

    def update(self) -> Status:
        """Fail once the deadline passes with the child still running, else mirror it."""
        child = self.decorated
        if child.status == Status.RUNNING and self.clock.now() >= self.deadline:
            detail = f" ({child.feedback_message})" if child.feedback_message else ""
            reason = f"{child.name}: timed out after {self.duration:g} s{detail}"
            child.stop(Status.INVALID)
            self.feedback_message = reason
            self.blackboard.set(keys.FAILURE_REASON, reason)
            return Status.FAILURE
        if child.status == Status.RUNNING:
            self.feedback_later("{:.1f} s left", self.deadline - self.clock.now())
        return child.status


class RetryWhileBattery(Retry):
    """Retry a failed child while the battery allows another try (DESIGN.md section 5: the
    landing tries run "for a fixed number of attempts, or while the battery allows").

    Like py_trees' :class:`~py_trees.decorators.Retry` (at most ``num_failures`` tries), but
    a new try after a failed one starts only if
    ``battery - expected_cost >= critical``, where ``expected_cost`` is the larger of
    ``attempt_cost`` and the largest battery drop (percentage points, battery at the start
    of a try minus battery when it finished) of any try finished so far in this flight: it
    learns what a try really costs. The first try is always allowed (the mission's battery
    reserve pays for it). An unknown battery level (None) does not guard: it behaves like
    Retry. The largest drop is kept across re-entries of the decorator (one flight per tree).
    No clock is read.

    * SUCCESS: the child succeeded
    * RUNNING: the child is running, or it failed and another try starts on the next tick
    * FAILURE: the child failed ``num_failures`` times, or it failed and the battery leaves
      no room for another try; then the reason, in numbers ("battery 21.3 % leaves no room
      for another try: a try has cost up to 6.2 %, critical level 15 %"), goes to the
      feedback message and :data:`behaviors.blackboard.FAILURE_REASON`

    Args:
        name: the decorator name
        child: the child behaviour or subtree (one try)
        vehicle: the vehicle port whose ``state.battery_percent`` is read (percent or None)
        num_failures: maximum number of tries, >= 1
        critical: battery level (%) no new try may be expected to cross
        attempt_cost: battery (% points) a try is assumed to cost at least, >= 0
        expected_cost_key: blackboard key to which :attr:`expected_cost` is written
            whenever it changes (from construction on), e.g. for
            :class:`behaviors.failsafe.BatteryAllows`; None writes nothing
    """

    def __init__(
        self,
        name: str,
        child: py_trees.behaviour.Behaviour,
        vehicle: VehiclePort,
        num_failures: int,
        critical: float,
        attempt_cost: float,
        expected_cost_key: str | None = None,
    ) -> None:
        if num_failures < 1:
            raise ValueError(f"num_failures must be >= 1, got {num_failures}")
        if not attempt_cost >= 0:
            raise ValueError(f"attempt_cost must be >= 0 %, got {attempt_cost}")
        super().__init__(name=name, child=child, num_failures=num_failures)
        self.vehicle = vehicle
        self.critical = float(critical)
        self.attempt_cost = float(attempt_cost)
        self.largest_drop = 0.0
        """Largest battery drop (% points) of a finished try in this flight."""
        self.try_start: float | None = None
        self.blackboard = self.attach_blackboard_client(self.name)
        self.blackboard.register_key(key=keys.FAILURE_REASON, access=Access.WRITE)
        self.expected_cost_key = expected_cost_key
        if expected_cost_key is not None:
            self.blackboard.register_key(key=expected_cost_key, access=Access.WRITE)
            self.blackboard.set(expected_cost_key, self.expected_cost)

    @property
    def expected_cost(self) -> float:
        """Battery (% points) the next try is expected to cost."""
        return max(self.attempt_cost, self.largest_drop)

    def initialise(self) -> None:
        """Start counting tries; the first one starts now, whatever the battery."""
        super().initialise()
        self.try_start = self.vehicle.state.battery_percent

    def update(self) -> Status:
        """Mirror the child; after a failed try, start another only if the battery allows."""
        child = self.decorated
        if child.status not in (Status.SUCCESS, Status.FAILURE):
            return super().update()
        battery = self.vehicle.state.battery_percent
        if battery is not None and self.try_start is not None:
            self.largest_drop = max(self.largest_drop, self.try_start - battery)
            if self.expected_cost_key is not None:
                self.blackboard.set(self.expected_cost_key, self.expected_cost)
        status = super().update()
        if status != Status.RUNNING:
            return status
        # The child failed and Retry would try again.
        if not battery_leaves_room(battery, self.expected_cost, self.critical):
            reason = (
                f"battery {battery:.1f} % leaves no room for another try: a try has cost up "
                f"to {self.largest_drop:.1f} % (at least {self.attempt_cost:g} % assumed), "
                f"critical level {self.critical:g} %"
            )
            self.feedback_message = reason
            self.blackboard.set(keys.FAILURE_REASON, f"{self.name}: {reason}")
            return Status.FAILURE
        self.try_start = battery
        return status
