"""Failsafe conditions: battery reserve and critical levels, GPS loss, and the guard that
keeps a mission ended by a failsafe from restarting."""

from __future__ import annotations

from collections.abc import Callable

from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.base import MissionBehaviour
from behaviors.flight import GPS_FIX_3D
from behaviors.ports import Clock, VehiclePort
from behaviors.ticking import QuietBehaviour


def battery_below(vehicle: VehiclePort, level: float) -> bool:
    """True when the vehicle reports a battery level at or below ``level`` percent."""
    battery = vehicle.state.battery_percent
    return battery is not None and battery <= level


class BatteryReserve(MissionBehaviour):
    """Condition: the battery is at or below the reserve level.

    The first time it holds it writes "battery_reserve" to OUTCOME_HINT (if no hint yet).

    * SUCCESS: battery known and <= ``level`` %
    * FAILURE: otherwise
    """

    def __init__(self, name: str, vehicle: VehiclePort, level: float) -> None:
        super().__init__(name)
        self.vehicle = vehicle
        self.level = float(level)
        self.blackboard.register_key(key=keys.OUTCOME_HINT, access=Access.WRITE)

    def update(self) -> Status:
        if not battery_below(self.vehicle, self.level):
            self.feedback_later("battery above {:g} %", self.level)
            return Status.FAILURE
        if self.blackboard.get(keys.OUTCOME_HINT) is None:
            self.blackboard.set(keys.OUTCOME_HINT, "battery_reserve")
        self.feedback_message = f"battery at or below the reserve {self.level:g} %"
        return Status.SUCCESS


def battery_leaves_room(battery: float | None, cost: float, critical: float) -> bool:
    """True when a flight costing ``cost`` percentage points from ``battery`` % stays at or
    above the ``critical`` level; an unknown level (None) does not guard."""
    return battery is None or battery - cost >= critical


class BatteryAllows(MissionBehaviour):
    """Condition: the battery leaves room for a flight expected to cost ``cost()`` percentage
    points without reaching the ``critical`` level (``battery - cost() >= critical``).
    ``cost`` may instead be a blackboard key holding the cost (None there counts as 0).

    * SUCCESS: the battery allows it, or its level is unknown (then nothing guards)
    * FAILURE: the flight could end below the critical level
    """

    def __init__(
        self, name: str, vehicle: VehiclePort, critical: float,
        cost: Callable[[], float] | str,
    ) -> None:
        super().__init__(name)
        self.vehicle = vehicle
        self.critical = float(critical)
        if isinstance(cost, str):
            key = cost
            self.blackboard.register_key(key=key, access=Access.READ)
            cost = lambda: self.blackboard.get(key) or 0.0  # noqa: E731
        self.cost = cost

    def update(self) -> Status:
        battery = self.vehicle.state.battery_percent
        if battery is None:
            self.feedback_message = "battery level unknown"
            return Status.SUCCESS
        cost = self.cost()
        if not battery_leaves_room(battery, cost, self.critical):
            self.feedback_message = (
                f"battery {battery:.1f} % leaves no room for a flight of up to {cost:.1f} % "
                f"above the critical {self.critical:g} %"
            )
            return Status.FAILURE
        self.feedback_message = f"battery {battery:.1f} %, a flight costs up to {cost:.1f} %"
        return Status.SUCCESS


class LatchedFailsafe(MissionBehaviour):
    """Base of the failsafe conditions: once :meth:`triggered` holds, write ``kind`` to
    FAILSAFE and OUTCOME_HINT and the "failsafe" phase, and keep succeeding from then on
    (FAILSAFE set by any failsafe counts: one failsafe takes over at a time).

    * SUCCESS: triggered now or earlier in this mission
    * FAILURE: otherwise
    """

    kind = "failsafe"

    def __init__(self, name: str, vehicle: VehiclePort) -> None:
        super().__init__(name)
        self.vehicle = vehicle
        self.blackboard.register_key(key=keys.FAILSAFE, access=Access.WRITE)
        self.blackboard.register_key(key=keys.OUTCOME_HINT, access=Access.WRITE)

    def triggered(self) -> str | None:
        """Why the failsafe must take over now, or None."""
        raise NotImplementedError

    def update(self) -> Status:
        if self.peek(keys.FAILSAFE) is not None:
            return Status.SUCCESS
        why = self.triggered()
        if why is None:
            return Status.FAILURE
        self.blackboard.set(keys.FAILSAFE, self.kind)
        self.blackboard.set(keys.OUTCOME_HINT, self.kind)
        self.blackboard.set(keys.PHASE, "failsafe")
        self.feedback_message = why
        return Status.SUCCESS


class BatteryCritical(LatchedFailsafe):
    """Latched condition: the armed vehicle's battery reached ``level`` percent
    (FAILSAFE / OUTCOME_HINT "battery_critical").

    * SUCCESS: armed with battery <= ``level`` % now, or any failsafe latched earlier
    * FAILURE: otherwise
    """

    kind = "battery_critical"

    def __init__(self, name: str, vehicle: VehiclePort, level: float) -> None:
        super().__init__(name, vehicle)
        self.level = float(level)

    def triggered(self) -> str | None:
        if self.vehicle.state.armed and battery_below(self.vehicle, self.level):
            return f"battery at or below the critical {self.level:g} %"
        self.feedback_later("battery above {:g} % (or disarmed)", self.level)
        return None


class GpsLost(LatchedFailsafe):
    """Latched condition: the armed vehicle has had no 3D GPS fix for ``timeout`` clock
    seconds (FAILSAFE / OUTCOME_HINT "gps_lost"); short dropouts are ridden out.

    * SUCCESS: armed without a 3D fix for ``timeout`` s, or any failsafe latched earlier
    * FAILURE: otherwise
    """

    kind = "gps_lost"

    def __init__(self, name: str, vehicle: VehiclePort, clock: Clock, timeout: float) -> None:
        super().__init__(name, vehicle)
        self.clock = clock
        self.timeout = float(timeout)
        self.lost_since: float | None = None

    def triggered(self) -> str | None:
        state = self.vehicle.state
        if not state.armed or state.gps_fix >= GPS_FIX_3D:
            self.lost_since = None
            self.feedback_message = "3D fix (or disarmed)"
            return None
        now = self.clock.now()
        if self.lost_since is None:
            self.lost_since = now
        lost_for = now - self.lost_since
        if lost_for >= self.timeout:
            return f"no 3D GPS fix for {lost_for:.1f} s"
        self.feedback_message = f"no 3D GPS fix for {lost_for:.1f} s"
        return None


class NoFailsafe(QuietBehaviour):
    """Condition: no failsafe has taken over the mission.

    Guards the mission branch so that it cannot restart after a failsafe ended it.

    * SUCCESS: FAILSAFE is None
    * FAILURE: a failsafe is latched
    """

    def __init__(self, name: str = "No failsafe?") -> None:
        super().__init__(name=name)
        self.blackboard = self.attach_blackboard_client(name)
        self.blackboard.register_key(key=keys.FAILSAFE, access=Access.READ)

    def update(self) -> Status:
        failsafe = self.blackboard.get(keys.FAILSAFE)
        if failsafe is None:
            return Status.SUCCESS
        self.feedback_message = f"failsafe {failsafe} took over"
        return Status.FAILURE
