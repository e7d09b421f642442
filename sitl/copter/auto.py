"""Flying the stored mission: ArduPilot Copter's AUTO mode, PX4's AUTO.MISSION.

Items run one after the other. NAV items (take-off, waypoint, loiter, delay, land, return to
launch) fly until they complete and are then reported as reached; DO and CONDITION items run at
once (a speed change, a jump) or are skipped when the vehicle has nothing they could act on
(camera, servo, gimbal). ArduPilot runs a DO item together with the NAV item before it; here it
runs when its turn comes, which changes nothing for the items the simulator models.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .kinematics import Setpoint
from .mission import MissionItem

if TYPE_CHECKING:
    from .autopilot import Autopilot

NOT_STARTED = mavlink.MISSION_STATE_NOT_STARTED
ACTIVE = mavlink.MISSION_STATE_ACTIVE
PAUSED = mavlink.MISSION_STATE_PAUSED
COMPLETE = mavlink.MISSION_STATE_COMPLETE
NO_MISSION = mavlink.MISSION_STATE_NO_MISSION

_C = mavlink
_GO_TO_POINT = frozenset({
    _C.MAV_CMD_NAV_WAYPOINT, _C.MAV_CMD_NAV_SPLINE_WAYPOINT, _C.MAV_CMD_NAV_LOITER_TIME,
    _C.MAV_CMD_NAV_LOITER_UNLIM, _C.MAV_CMD_NAV_LOITER_TURNS, _C.MAV_CMD_NAV_LOITER_TO_ALT,
})
_NAV = _GO_TO_POINT | {
    _C.MAV_CMD_NAV_TAKEOFF, _C.MAV_CMD_NAV_LAND, _C.MAV_CMD_NAV_RETURN_TO_LAUNCH,
    _C.MAV_CMD_NAV_DELAY,
}
_TAKEOFF_REACHED = 0.3  # m below the take-off altitude that counts as reached
_MAX_ITEMS_PER_STEP = 64  # DO items run in one step at most (a DO_JUMP loop cannot stall)


class AutoFlier:
    """Flies ``autopilot.mission`` in AUTO; :meth:`setpoint` is called every physics step.

    ``state`` is a MISSION_STATE; ``reached`` collects the sequence numbers of the items
    completed since the server last sent MISSION_ITEM_REACHED.
    """

    def __init__(self, autopilot: Autopilot) -> None:
        self.ap = autopilot
        self.store = autopilot.mission
        self.state = NOT_STARTED
        self.reached: list[int] = []
        self.landing = False  # a NAV_LAND or return-to-launch descent is under way
        self._version = self.store.changed
        self._jumps_done: dict[int, int] = {}
        self._target: tuple[float, float, float] | None = None
        self._arrived_at: float | None = None
        self._phase = ""

    # ------------------------------------------------------------------ control
    @property
    def mission_state(self) -> int:
        if not self.store.has_mission():
            return NO_MISSION
        return self.state

    def start(self, *, restart: bool = False) -> None:
        """Run from the current item (or from the first when ``restart`` or the mission
        was completed)."""
        if restart or self.state == COMPLETE:
            self.store.current = self.store.first
            self._jumps_done.clear()
        self.state = ACTIVE
        self._begin()

    def resume_at_current(self) -> None:
        """The current item was set from outside: a completed mission resumes there."""
        if self.state == COMPLETE:
            self.state = PAUSED

    def pause(self) -> None:
        """The vehicle left AUTO: the mission stops where it is (it resumes there)."""
        if self.state == ACTIVE:
            self.state = PAUSED
        self.landing = False

    def setpoint(self, agl: float) -> Setpoint:
        """The setpoint for this physics step while in AUTO."""
        ap = self.ap
        if self.state == COMPLETE:
            return ap.on_mission_complete()
        if self.state != ACTIVE:
            return Setpoint(position=ap.hold, hold_ground=not ap.flying)
        if self.store.changed != self._version:
            self._begin()
        for _ in range(_MAX_ITEMS_PER_STEP):
            item = self._item()
            if item is None:  # the plan was replaced by a shorter one under us
                self.state = COMPLETE
            if self.state == COMPLETE:
                self.landing = False
                return ap.on_mission_complete()
            if item.command in _NAV:
                return self._fly(item, agl)
            self._run_do_item(item)
        return Setpoint(position=ap.model.position, hold_ground=not ap.flying)

    # ------------------------------------------------------------------ items
    def _item(self) -> MissionItem | None:
        items = self.store.items
        seq = self.store.current
        return items[seq] if self.store.first <= seq < len(items) else None

    def _begin(self) -> None:
        """Start the current item afresh."""
        self._version = self.store.changed
        self._target = None
        self._arrived_at = None
        self._phase = ""
        self.landing = False

    def _advance(self, reached: bool) -> None:
        """On to the next item; after the last one the mission is complete and the current
        item stays the last (MISSION_CURRENT then reports seq == total, state COMPLETE)."""
        if reached:
            self.reached.append(self.store.current)
        if self.store.current + 1 < len(self.store.items):
            self.store.current += 1
            self.store.changed += 1
        else:
            self.state = COMPLETE
        self._begin()

    def _run_do_item(self, item: MissionItem) -> None:
        ap = self.ap
        seq = self.store.current
        if item.command == _C.MAV_CMD_DO_JUMP:
            target, repeat = int(_finite(item.param1, -1)), int(_finite(item.param2, 0))
            done = self._jumps_done.get(seq, 0)
            if self.store.first <= target < len(self.store.items) and (
                repeat < 0 or done < repeat
            ):
                self._jumps_done[seq] = done + 1
                self.store.current = target
                self.store.changed += 1
                self._begin()
                return
        elif item.command == _C.MAV_CMD_DO_CHANGE_SPEED:
            speed = _finite(item.param2, -1.0)
            if speed > 0:
                ap.change_speed(int(_finite(item.param1, 1)), speed)
        self._advance(reached=False)

    def _fly(self, item: MissionItem, agl: float) -> Setpoint:
        ap = self.ap
        m = ap.model
        cmd = item.command
        if cmd == _C.MAV_CMD_NAV_TAKEOFF:
            return self._takeoff(item)
        if not ap.flying:
            if ap.implicit_takeoff_altitude() is not None and cmd != _C.MAV_CMD_NAV_LAND:
                return self._implicit_takeoff()
            # On the ground at a NAV item that does not take off: nothing to fly yet.
            return Setpoint(position=m.position, hold_ground=True)
        if cmd == _C.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self._return(agl)
        if cmd == _C.MAV_CMD_NAV_LAND:
            return self._land(item, agl)
        if cmd == _C.MAV_CMD_NAV_DELAY:
            return self._delay(item)
        return self._go_to(item)

    def _takeoff(self, item: MissionItem) -> Setpoint:
        ap = self.ap
        m = ap.model
        if self._target is None:
            point = None
            if item.is_global:
                point = ap.geo.to_enu(None, None, _finite(item.z, 0.0), item.frame, m.position)
            z = point[2] if point is not None else ap.home_z + _finite(item.z, 0.0)
            self._target = (m.x, m.y, max(z, m.z))
            if not ap.flying:
                ap.lift_off()
        if m.z >= self._target[2] - _TAKEOFF_REACHED:
            self._advance(reached=True)
            return Setpoint(position=self._target)
        return Setpoint(position=self._target, max_speed=ap.speed_limit)

    def _implicit_takeoff(self) -> Setpoint:
        """PX4 climbs to MIS_TAKEOFF_ALT before a mission that starts on the ground without a
        take-off item."""
        ap = self.ap
        m = ap.model
        if self._phase != "implicit_takeoff":
            self._phase = "implicit_takeoff"
            self._target = (m.x, m.y, ap.home_z + ap.implicit_takeoff_altitude())
            ap.lift_off()
        return Setpoint(position=self._target)

    def _go_to(self, item: MissionItem) -> Setpoint:
        ap = self.ap
        m = ap.model
        now = ap.time
        if self._target is None or self._phase == "implicit_takeoff":
            self._phase = ""
            self._target = self._point(item)
        target = self._target
        if self._arrived_at is None:
            dist = math.dist(m.position, target)
            if dist > ap.waypoint_radius:
                return Setpoint(position=target, max_speed=ap.speed_limit)
            self._arrived_at = now
        cmd = item.command
        if cmd == _C.MAV_CMD_NAV_LOITER_UNLIM:
            return Setpoint(position=target)
        wait = 0.0
        if cmd in (_C.MAV_CMD_NAV_WAYPOINT, _C.MAV_CMD_NAV_SPLINE_WAYPOINT,
                   _C.MAV_CMD_NAV_LOITER_TIME):
            wait = max(0.0, _finite(item.param1, 0.0))
        if now - self._arrived_at >= wait - 1e-9:
            self._advance(reached=True)
        return Setpoint(position=target)

    def _delay(self, item: MissionItem) -> Setpoint:
        ap = self.ap
        if self._target is None:
            self._target = ap.model.position
            self._arrived_at = ap.time
        if ap.time - self._arrived_at >= max(0.0, _finite(item.param1, 0.0)) - 1e-9:
            self._advance(reached=True)
        return Setpoint(position=self._target)

    def _land(self, item: MissionItem, agl: float) -> Setpoint:
        ap = self.ap
        m = ap.model
        if self._target is None:
            x, y = m.x, m.y
            if item.is_global and (item.x != 0.0 or item.y != 0.0):
                point = ap.geo.to_enu(item.x, item.y, None, item.frame, m.position)
                if point is not None:
                    x, y = point[0], point[1]
            self._target = (x, y, m.z)
        x, y, z = self._target
        if self._phase != "descend":
            if math.hypot(m.x - x, m.y - y) > ap.waypoint_radius:
                return Setpoint(position=(x, y, z), max_speed=ap.speed_limit)
            self._phase = "descend"
            self.landing = True
        return ap.land_setpoint(x, y, agl)

    def _return(self, agl: float) -> Setpoint:
        ap = self.ap
        if self._phase != "return":
            self._phase = "return"
            ap.begin_return()
        setpoint = ap.return_setpoint(agl)
        self.landing = ap.rtl_phase == "land"
        return setpoint

    def _point(self, item: MissionItem) -> tuple[float, float, float]:
        """A NAV item's point; lat = lon = 0 keeps the current position and an altitude of 0
        the current altitude, as ArduPilot does."""
        ap = self.ap
        m = ap.model
        lat = lon = alt = None
        if item.is_global:
            if item.x != 0.0 or item.y != 0.0:
                lat, lon = item.x, item.y
            if item.z != 0.0:
                alt = item.z
        point = ap.geo.to_enu(lat, lon, alt, item.frame, m.position)
        return point if point is not None else m.position

    def on_landed(self) -> None:
        """The vehicle touched down during a NAV_LAND or return: the item is done."""
        if self.state == ACTIVE and self.landing:
            self._advance(reached=True)
            self.landing = False


def _finite(value: float, default: float) -> float:
    return float(value) if math.isfinite(value) else default
