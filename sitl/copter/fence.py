"""Geofence enforcement, as each autopilot does it.

The zones come from the fence plan (MAV_MISSION_TYPE_FENCE: inclusion and exclusion polygons
and circles) plus each autopilot's own limits around home: ArduPilot's cylinder (FENCE_RADIUS,
FENCE_ALT_MAX, AC_Fence) and PX4's GF_MAX_HOR_DIST / GF_MAX_VER_DIST (navigator's Geofence).
Nothing is checked unless a fence is in force (ArduPilot: FENCE_ENABLE or
MAV_CMD_DO_FENCE_ENABLE; PX4: a fence plan or a GF_MAX_* above 0, with GF_ACTION not 0), and
then only at the autopilot's own check rate, so an ordinary flight pays one comparison per
physics step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from matplotlib.path import Path
from pymavlink.dialects.v20 import ardupilotmega as mavlink

if TYPE_CHECKING:
    from .autopilot import Autopilot

# AC_Fence.h: FENCE_TYPE bits.
ALT_MAX, CIRCLE, POLYGON, ALT_MIN = 1, 2, 4, 8
_NAMES = ((ALT_MAX, "Max Alt"), (CIRCLE, "Circle"), (POLYGON, "Polygon"), (ALT_MIN, "Min Alt"))
# AC_Fence.h: a breach this far (m) beyond the fence lands instead (AC_FENCE_GIVE_UP_DISTANCE);
# a second breach of a fence already breached counts this far (m) out (the backup fences).
_GIVE_UP_DISTANCE = 100.0
_BACKUP_DISTANCE = 20.0
# ArduCopter checks its fence at 25 Hz (fence_checks_async), PX4's navigator every 200 ms
# (GEOFENCE_CHECK_INTERVAL_US).
_ARDUPILOT_PERIOD = 0.04
_PX4_PERIOD = 0.2

_C = mavlink
_POLYGON_INCLUSION = _C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
_POLYGON_EXCLUSION = _C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
_CIRCLE_INCLUSION = _C.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
_CIRCLE_EXCLUSION = _C.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION


@dataclass
class Zones:
    """A fence plan in local ENU metres: polygons as vertex arrays, circles as rows of
    (x, y, radius)."""

    inclusion: list[np.ndarray] = field(default_factory=list)
    exclusion: list[np.ndarray] = field(default_factory=list)
    inclusion_circles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    exclusion_circles: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self) -> None:
        self._paths: tuple[list[Path], list[Path]] | None = None

    def __bool__(self) -> bool:
        return bool(self.inclusion or self.exclusion or len(self.inclusion_circles)
                    or len(self.exclusion_circles))

    def inside_each(self, x: float, y: float) -> tuple[list[bool], list[bool], np.ndarray,
                                                        np.ndarray]:
        """Whether (x, y) is inside each inclusion polygon, each exclusion polygon, each
        inclusion circle and each exclusion circle."""
        if self._paths is None:  # built once per plan
            self._paths = ([Path(v) for v in self.inclusion], [Path(v) for v in self.exclusion])
        p = (x, y)
        inc = [path.contains_point(p) for path in self._paths[0]]
        exc = [path.contains_point(p) for path in self._paths[1]]
        ic, ec = self.inclusion_circles, self.exclusion_circles
        in_ic = np.hypot(ic[:, 0] - x, ic[:, 1] - y) <= ic[:, 2]
        in_ec = np.hypot(ec[:, 0] - x, ec[:, 1] - y) < ec[:, 2]
        return inc, exc, in_ic, in_ec

    def breached_intersection(self, x: float, y: float) -> bool:
        """ArduPilot (AC_PolyFence_loader::breached): outside any inclusion zone or inside
        any exclusion zone."""
        inc, exc, in_ic, in_ec = self.inside_each(x, y)
        return not all(inc) or any(exc) or not bool(np.all(in_ic)) or bool(np.any(in_ec))

    def breached_union(self, x: float, y: float) -> bool:
        """PX4 (Geofence::isInsidePolygonOrCircle): outside every inclusion zone (when there
        is one) or inside an exclusion zone."""
        inc, exc, in_ic, in_ec = self.inside_each(x, y)
        has_inclusion = bool(inc) or len(in_ic) > 0
        inside = any(inc) or bool(np.any(in_ic))
        return (has_inclusion and not inside) or any(exc) or bool(np.any(in_ec))

    def distance_outside(self, x: float, y: float) -> float:
        """How far (m) (x, y) is beyond the zone it breaches, for ArduPilot's 100 m rule:
        the distance to the nearest edge or circle."""
        best = math.inf
        for v in (*self.inclusion, *self.exclusion):
            a, b = v, np.roll(v, -1, axis=0)
            ab = b - a
            t = np.clip(((x - a[:, 0]) * ab[:, 0] + (y - a[:, 1]) * ab[:, 1])
                        / np.maximum((ab ** 2).sum(axis=1), 1e-12), 0.0, 1.0)
            d = np.hypot(a[:, 0] + t * ab[:, 0] - x, a[:, 1] + t * ab[:, 1] - y)
            best = min(best, float(d.min()))
        for c in (self.inclusion_circles, self.exclusion_circles):
            if len(c):
                d = np.abs(np.hypot(c[:, 0] - x, c[:, 1] - y) - c[:, 2])
                best = min(best, float(d.min()))
        return 0.0 if best == math.inf else best


def zones_from_plan(items, to_local) -> Zones:
    """The zones of a fence plan's items; ``to_local(lat, lon) -> (east, north)``. A polygon
    is a run of vertex items of one kind, param1 its vertex count (MAVLink's fence protocol)."""
    zones = Zones()
    inc_c, exc_c = [], []
    i = 0
    while i < len(items):
        item = items[i]
        cmd = item.command
        if cmd in (_POLYGON_INCLUSION, _POLYGON_EXCLUSION):
            n = int(item.param1) if math.isfinite(item.param1) and item.param1 >= 3 else 0
            run = items[i:i + n] if n else []
            if n and len(run) == n and all(it.command == cmd for it in run):
                vertices = np.array([to_local(it.x, it.y) for it in run], dtype=float)
                if np.isfinite(vertices).all():
                    (zones.inclusion if cmd == _POLYGON_INCLUSION else zones.exclusion).append(
                        vertices)
                i += n
                continue
        elif cmd in (_CIRCLE_INCLUSION, _CIRCLE_EXCLUSION) and item.param1 > 0:
            east, north = to_local(item.x, item.y)
            if math.isfinite(east) and math.isfinite(north):
                (inc_c if cmd == _CIRCLE_INCLUSION else exc_c).append((east, north, item.param1))
        i += 1
    if inc_c:
        zones.inclusion_circles = np.array(inc_c, dtype=float)
    if exc_c:
        zones.exclusion_circles = np.array(exc_c, dtype=float)
    return zones


def fence_names(fences: int) -> str:
    """AC_Fence::get_fence_names: "Polygon fence", "Max Alt and Circle fences", ..."""
    names = [name for bit, name in _NAMES if fences & bit]
    if not names:
        return ""
    text = names[0] if len(names) == 1 else ", ".join(names[:-1]) + " and " + names[-1]
    return text + (" fences" if len(names) > 1 else " fence")


class Fence:
    """No geofence (the base of the personalities' fences)."""

    def __init__(self, autopilot: Autopilot) -> None:
        self.ap = autopilot
        self.breaches = 0  # bit mask of the fences breached now (FENCE_TYPE bits)
        self.breach_count = 0
        self.breach_time = 0.0  # s since boot of the last new breach
        self._next_check = 0.0
        self._plan = None
        self._zones = Zones()

    def zones(self) -> Zones:
        """The uploaded fence plan, converted once per upload."""
        plan = self.ap.mission.plans[_C.MAV_MISSION_TYPE_FENCE]
        if plan is not self._plan:
            self._plan = plan
            self._zones = zones_from_plan(plan, self.ap.geo.to_global.to_local)
        return self._zones

    def _param(self, name: str) -> float:
        return self.ap.params.stored(name)

    def _where(self, position=None) -> tuple[float, float, float, float, float]:
        """(x, y) in the local frame, (east, north) of home and the height above home (m) of
        ``position`` (ENU), or of the vehicle as its EKF knows it."""
        ap = self.ap
        if position is None:
            x, y = ap.estimated_xy()
            z = ap.model.z
        else:
            x, y, z = position
        hx, hy = ap.home_xy
        return x, y, x - hx, y - hy, z - ap.home_z

    def step(self) -> None:
        """After a physics step."""

    def prearm_failure(self) -> str | None:
        return None

    def allows(self, target) -> bool:
        """A guided target may be flown (ArduPilot refuses one beyond the fence)."""
        return True

    def enable(self, value: int | None) -> int:
        return _C.MAV_RESULT_UNSUPPORTED

    def sys_status(self) -> tuple[bool, bool, bool] | None:
        """(present, enabled, healthy) of SYS_STATUS's geofence bit, or None to leave it."""
        return None

    def status_message(self):
        return None


class ArduPilotFence(Fence):
    """AC_Fence with ArduCopter's response (ArduCopter/fence.cpp)."""

    def __init__(self, autopilot: Autopilot) -> None:
        super().__init__(autopilot)
        self._enable_param = 0.0
        self.enabled_fences = 0  # AC_Fence::_enabled_fences
        self._backup: dict[int, float] = {}  # fence bit -> its backup fence (0: none)

    def _sync(self) -> None:
        # AC_Fence::update: a change of FENCE_ENABLE enables or disables every configured
        # fence but the floor.
        enable = self._param("FENCE_ENABLE")
        if enable != self._enable_param:
            self._enable_param = enable
            self.enabled_fences = (int(self._param("FENCE_TYPE")) & ~ALT_MIN) if enable else 0

    def present(self) -> int:
        """AC_Fence::present: the configured fences, the polygon only with a plan."""
        mask = CIRCLE | ALT_MIN | ALT_MAX | (POLYGON if self.zones() else 0)
        return int(self._param("FENCE_TYPE")) & mask

    def enabled(self) -> int:
        return self.enabled_fences & self.present()

    def enable(self, value: int | None) -> int:
        """MAV_CMD_DO_FENCE_ENABLE (GCS_Fence.cpp): 0 disables, 1 enables, 2 disables the
        floor only (not modelled); anything else fails."""
        self._sync()
        if value == 1:
            self.enabled_fences |= int(self._param("FENCE_TYPE")) & ~ALT_MIN
        elif value == 0:
            self.enabled_fences = 0
            self.breaches = 0
        elif value != 2:
            return _C.MAV_RESULT_FAILED
        return _C.MAV_RESULT_ACCEPTED

    def _check(self) -> tuple[int, int, float]:
        """(breached now, newly breached, distance beyond the new breaches), as
        AC_Fence::check does, with its backup fences 20 m further out."""
        fences = self.enabled()
        x, y, east, north, alt = self._where()
        now = new = 0
        distance = -math.inf
        for bit, value, limit in ((ALT_MAX, alt, "FENCE_ALT_MAX"),
                                  (CIRCLE, math.hypot(east, north), "FENCE_RADIUS")):
            if fences & bit:
                beyond = self._beyond(bit, value, self._param(limit))
                if beyond is not None:
                    now |= bit
                    if beyond >= 0:
                        new |= bit
                        distance = max(distance, beyond)
        if fences & POLYGON:
            zones = self.zones()
            if zones.breached_intersection(x, y):
                now |= POLYGON
                if not self.breaches & POLYGON:
                    new |= POLYGON
                    distance = max(distance, zones.distance_outside(x, y))
        return now, new, distance

    def _beyond(self, bit: int, value: float, limit: float) -> float | None:
        """A distance-like fence (altitude, radius): None inside it; else how far beyond
        the limit a new breach is, or -1 for a breach already reported and still short of
        its backup fence, which then moves 20 m further out (AC_Fence's backup fences)."""
        if value < limit:
            self._backup[bit] = 0.0
            return None
        backup = self._backup.get(bit, 0.0)
        if self.breaches & bit and not (backup and value >= backup):
            return -1.0
        self._backup[bit] = value + _BACKUP_DISTANCE
        return value - limit

    def step(self) -> None:
        ap = self.ap
        if ap.time < self._next_check:
            return
        self._next_check = ap.time + _ARDUPILOT_PERIOD
        self._sync()
        if not self.enabled_fences:
            self.breaches = 0
            return
        before = self.breaches
        now, new, distance = self._check()
        self.breaches = now
        if new:
            if not before:
                self.breach_time = ap.time
            self.breach_count = min(self.breach_count + bin(new).count("1"), 65500)
            if ap.armed:
                self._respond(new, distance)
        elif before and not now and not ap.model.on_ground:
            ap.text(_C.MAV_SEVERITY_NOTICE, "Fence breach cleared")

    def _respond(self, new: int, distance: float) -> None:
        """Copter::fence_check: say which fences, then act per FENCE_ACTION."""
        ap = self.ap
        landed = ap.model.on_ground
        if not landed:
            ap.text(_C.MAV_SEVERITY_NOTICE, f"{fence_names(new)} breached")
        action = int(self._param("FENCE_ACTION"))
        if action == 0:  # report only
            return
        if landed:
            ap._disarm("Disarming motors")
            return
        if distance > _GIVE_UP_DISTANCE or action == 2:  # too far out, or always land
            chain = ("LAND",)
        elif action == 3:
            chain = ("SMART_RTL", "RTL", "LAND")
        elif action == 4:
            chain = ("BRAKE", "LAND")
        elif action == 5:
            chain = ("SMART_RTL", "LAND")
        else:  # 1 (RTL or land) and anything unknown
            chain = ("RTL", "LAND")
        for mode in chain:
            if ap.set_mode(mode) == _C.MAV_RESULT_ACCEPTED:
                break

    def prearm_failure(self) -> str | None:
        # AC_Fence::pre_arm_check, as AP_Arming::fence_checks reports it.
        self._sync()
        if self.enabled_fences and not self.present():
            return "Fences enabled, but none selected"
        if not self.enabled():
            return None
        now, _, _ = self._check()
        if now:
            return f"Vehicle breaching {fence_names(now)}"
        return None

    def allows(self, target) -> bool:
        # AC_Fence::check_destination_within_fence, which ModeGuided::set_destination asks.
        self._sync()
        fences = self.enabled()
        if not fences:
            return True
        x, y, east, north, alt = self._where(target)
        if fences & ALT_MAX and alt > self._param("FENCE_ALT_MAX"):
            return False
        if fences & CIRCLE and math.hypot(east, north) > self._param("FENCE_RADIUS"):
            return False
        return not (fences & POLYGON and self.zones().breached_intersection(x, y))

    def sys_status(self) -> tuple[bool, bool, bool]:
        # AC_Fence::sys_status_present/enabled/failed.
        self._sync()
        present = bool(self.present())
        enabled = present and int(self._param("FENCE_ACTION")) != 0 and bool(self.enabled())
        return present, enabled, not (present and self.breaches)

    def status_message(self):
        """FENCE_STATUS (GCS_MAVLINK::send_fence_status): only while a fence is enabled."""
        self._sync()
        if not self.enabled():
            return None
        b = self.breaches
        kind = _C.FENCE_BREACH_NONE
        if b & ALT_MIN:
            kind = _C.FENCE_BREACH_MINALT
        if b & ALT_MAX:
            kind = _C.FENCE_BREACH_MAXALT
        if b & (CIRCLE | POLYGON):
            kind = _C.FENCE_BREACH_BOUNDARY
        ms = int(self.breach_time * 1000.0) & 0xFFFFFFFF
        # No avoidance is modelled: nothing limits the velocity at the fence.
        return _C.MAVLink_fence_status_message(int(b != 0), self.breach_count, kind, ms,
                                               _C.FENCE_MITIGATE_NONE)


# PX4's geofence_violation_reason texts (commander's geofenceCheck.cpp).
_PX4_DIST = "Geofence violation: exceeding maximum distance to Home"
_PX4_ALT = "Geofence violation: exceeding maximum altitude above Home"
_PX4_FENCE = "Geofence violation: approaching or outside geofence"
_PX4_HOR, _PX4_VER, _PX4_ZONE = 1, 2, 4


class Px4Fence(Fence):
    """The navigator's Geofence and commander's failsafe for it (GF_ACTION: 0 none,
    1 warning, 2 Hold, 3 Return, 4 terminate, 5 Land; Failsafe::fromGfActParam)."""

    def _action(self) -> int:
        return int(self._param("GF_ACTION"))

    def _violations(self, position=None) -> int:
        hor = self._param("GF_MAX_HOR_DIST")
        ver = self._param("GF_MAX_VER_DIST")
        zones = self.zones()
        if not (hor > 0 or ver > 0 or zones):
            return 0
        x, y, east, north, alt = self._where(position)
        flags = 0
        if hor > 0 and math.hypot(east, north) > hor:
            flags |= _PX4_HOR
        if ver > 0 and alt > ver:
            flags |= _PX4_VER
        if zones and zones.breached_union(x, y):
            flags |= _PX4_ZONE
        return flags

    def _texts(self, flags: int) -> None:
        for bit, text in ((_PX4_HOR, _PX4_DIST), (_PX4_VER, _PX4_ALT), (_PX4_ZONE, _PX4_FENCE)):
            if flags & bit:
                self.ap.text(_C.MAV_SEVERITY_CRITICAL, text)

    def step(self) -> None:
        ap = self.ap
        if ap.time < self._next_check:
            return
        self._next_check = ap.time + _PX4_PERIOD
        action = self._action()
        now = self._violations() if action else 0
        before = self.breaches
        self.breaches = now
        if not now or before:
            return
        self.breach_count += 1
        self.breach_time = ap.time
        if not ap.armed:
            return
        # The failsafe acts once per breach; a mode change clears it (ClearCondition::
        # OnModeChangeOrDisarm), and a breach that goes on does not trigger it again.
        self._texts(now)
        if action == 2:
            ap._enter("AUTO.LOITER")
        elif action == 3:
            ap._enter("AUTO.RTL")
        elif action == 4:
            ap.terminate(True)
        elif action == 5:
            ap._enter("AUTO.LAND")

    def prearm_failure(self) -> str | None:
        # HealthAndArmingChecks' geofence check: a violation blocks arming unless GF_ACTION 0.
        if not self._action():
            return None
        flags = self._violations()
        if flags & _PX4_ZONE:
            return _PX4_FENCE
        if flags & _PX4_VER:
            return _PX4_ALT
        if flags & _PX4_HOR:
            return _PX4_DIST
        return None
