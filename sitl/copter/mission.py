"""The missions the simulated autopilot stores: items, their lists by mission type, the
current item.

Items are kept as they were uploaded (command, frame, params), with latitude and longitude in
degrees for global frames whichever message (MISSION_ITEM or MISSION_ITEM_INT) carried them,
so a download gives back what was uploaded. ArduPilot keeps home as item 0 of the flight plan
(an uploaded item 0 is replaced by home on download and never flown); PX4 does not.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

MISSION = mavlink.MAV_MISSION_TYPE_MISSION
FENCE = mavlink.MAV_MISSION_TYPE_FENCE
RALLY = mavlink.MAV_MISSION_TYPE_RALLY
TYPES = (MISSION, FENCE, RALLY)

GLOBAL_FRAMES = frozenset({
    mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_INT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,
})
# The MAV_CMD values the dialect knows: anything else in an upload is refused as unsupported.
KNOWN_COMMANDS = frozenset(mavlink.enums["MAV_CMD"])
KNOWN_FRAMES = frozenset(v for v in mavlink.enums["MAV_FRAME"] if v != mavlink.MAV_FRAME_ENUM_END)


@dataclass(frozen=True, slots=True)
class MissionItem:
    """One mission item. ``x``/``y`` are latitude/longitude in degrees in a global frame,
    else params 5 and 6 as sent; ``z`` is param 7 (the altitude in a global frame)."""

    command: int
    frame: int
    param1: float = 0.0
    param2: float = 0.0
    param3: float = 0.0
    param4: float = 0.0
    x: float = 0.0
    y: float = 0.0
    z: float = 0.0
    autocontinue: int = 1

    @property
    def is_global(self) -> bool:
        return self.frame in GLOBAL_FRAMES

    @classmethod
    def from_message(cls, msg) -> MissionItem:
        """From a MISSION_ITEM or MISSION_ITEM_INT (the latter's x/y are degrees * 1e7)."""
        x, y = float(msg.x), float(msg.y)
        if msg.get_type() == "MISSION_ITEM_INT" and msg.frame in GLOBAL_FRAMES:
            x, y = x * 1e-7, y * 1e-7
        elif msg.get_type() == "MISSION_ITEM_INT":
            x, y = float(int(msg.x)), float(int(msg.y))
        return cls(
            command=int(msg.command), frame=int(msg.frame),
            param1=float(msg.param1), param2=float(msg.param2),
            param3=float(msg.param3), param4=float(msg.param4),
            x=x, y=y, z=float(msg.z), autocontinue=int(msg.autocontinue),
        )

    def int_xy(self) -> tuple[int, int]:
        """x and y as MISSION_ITEM_INT carries them."""
        if self.is_global:
            return _int32(round(self.x * 1e7)), _int32(round(self.y * 1e7))
        return _int32(round(self.x)), _int32(round(self.y))


def _int32(v: float) -> int:
    return int(min(max(v, -(2**31)), 2**31 - 1))


def problem(item: MissionItem) -> int | None:
    """The MAV_MISSION_RESULT refusing ``item``, or None when it can be stored."""
    if item.command not in KNOWN_COMMANDS:
        return mavlink.MAV_MISSION_UNSUPPORTED
    if item.frame not in KNOWN_FRAMES:
        return mavlink.MAV_MISSION_UNSUPPORTED_FRAME
    if item.is_global:
        if not math.isfinite(item.x) or not -90.0 <= item.x <= 90.0:
            return mavlink.MAV_MISSION_INVALID_PARAM5_X
        if not math.isfinite(item.y) or not -180.0 <= item.y <= 180.0:
            return mavlink.MAV_MISSION_INVALID_PARAM6_Y
    return None


class MissionStore:
    """The stored plans (mission, fence, rally) and the current mission item.

    Args:
        home_at_zero: item 0 of the mission is home (ArduPilot).
        capacity: the most items one plan may hold.
    """

    def __init__(self, *, home_at_zero: bool, capacity: int) -> None:
        self.home_at_zero = home_at_zero
        self.capacity = capacity
        self.plans: dict[int, list[MissionItem]] = {t: [] for t in TYPES}
        self.first = 1 if home_at_zero else 0  # the first item that is flown
        self.current = self.first
        self.changed = 0  # bumped on every upload or clear, so the flier restarts its state

    def count(self, mission_type: int = MISSION) -> int:
        """Items a download reports (with ArduPilot's home item, even when no mission)."""
        items = self.plans[mission_type]
        if mission_type == MISSION and self.home_at_zero:
            return max(1, len(items))
        return len(items)

    @property
    def items(self) -> list[MissionItem]:
        return self.plans[MISSION]

    def has_mission(self) -> bool:
        """At least one item that can be flown."""
        return len(self.items) > self.first

    def replace(self, mission_type: int, items: list[MissionItem]) -> None:
        self.plans[mission_type] = list(items)
        if mission_type == MISSION:
            self.changed += 1
            if self.current >= len(items):
                self.current = self.first

    def clear(self, mission_type: int) -> None:
        types = TYPES if mission_type == mavlink.MAV_MISSION_TYPE_ALL else (mission_type,)
        for t in types:
            self.replace(t, [])

    def set_current(self, seq: int) -> bool:
        """Make ``seq`` the current item; False when there is no such item to fly."""
        if not self.first <= seq < len(self.items):
            return False
        self.current = seq
        self.changed += 1
        return True
