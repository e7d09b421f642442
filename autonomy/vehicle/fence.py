"""The mission's operating area as the autopilot's own geofence.

What is uploaded (docs/reference/mission-file.md#geofence):

* the polygon as one inclusion zone of the fence plan (MAV_MISSION_TYPE_FENCE): one
  MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION item per vertex, param1 = the vertex count,
  lat/lon in 1e7 degrees, MAV_FRAME_GLOBAL, as ArduPilot's autotest
  (``upload_fences_from_locations``) and MAVProxy's fence module send them. ArduPilot
  (GCS_MAVLink/MissionItemProtocol_Fence.cpp, AC_PolyFence_loader) and PX4 (navigator's
  Geofence) read a polygon as a run of param1 vertices of one kind; PX4's own tests send
  MAV_FRAME_GLOBAL_INT, and its mission manager reads either global frame of a
  MISSION_ITEM_INT as 1e7 degrees. The vertices are placed with the autopilot's own
  projection about its home (:func:`autonomy.vehicle.frames.local_to_geodetic`), so the
  fence lies where the flight's ENU polygon is;
* the mission's no-fly zones (``geofence.exclude``) after it: each polygon a run of
  MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION items (param1 = its vertex count), sent and
  projected as the inclusion vertices are, then each circle one
  MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION item (param1 = the radius in m, its centre's lat/lon
  as a vertex's), as MAVProxy's fence module and ArduPilot's autotest send them;
* the ceiling, when the mission gives one: ArduPilot FENCE_ALT_MAX, PX4 GF_MAX_VER_DIST
  (both metres above home);
* ArduPilot only: FENCE_TYPE = polygon (+ max altitude with a ceiling; AC_Fence.h bits 4 and
  1; the polygon bit, AC_FENCE_TYPE_POLYGON, covers every zone of the fence plan, inclusion
  and exclusion polygons and circles alike: AC_PolyFence_loader checks them all; its
  circle bit 2 is only the FENCE_RADIUS circle about home), which also turns off that
  circle (AC_FENCE_TYPE_DEFAULT for Copter is 7: max altitude, circle of FENCE_RADIUS,
  300 m by default, which would end missions the area allows, and
  polygon) and floor, then MAV_CMD_DO_FENCE_ENABLE 1 (what MAVProxy's ``fence enable`` and
  the autotest's ``do_fence_enable`` send; GCS_Fence.cpp). PX4 checks an uploaded fence plan
  whenever GF_ACTION is not 0 (navigator's Geofence, GeofenceResult.msg), so nothing needs
  enabling there.

The vehicle's own fence plan is downloaded first. Its exclusion zones (no-fly polygons and
circles) and its return point are uploaded again after the operating area and the
mission's no-fly zones, so that a flight
never lifts a no-fly zone the operator put on the vehicle; its inclusion zones are replaced
by the operating area (both autopilots would otherwise hold the vehicle inside all or any of
them, which the mission's area does not intend). Without that download the fence is not
uploaded.

What happens on a breach stays the autopilot's own setting (FENCE_ACTION, GF_ACTION): the user
chooses it on the vehicle, as with every other failsafe. It is read back and reported, with a
warning when it would not keep the vehicle in (ArduPilot 0: report only; PX4 0 or 1: none or a
warning).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.vehicle import frames
from autonomy.vehicle.commands import Handle
from autonomy.vehicle.transfers import ItemFields
from behaviors.ports import CommandStatus
from lsm.area import NoFlyCircle, NoFlyZone

# AC_Fence.h: FENCE_TYPE bits.
ARDUPILOT_ALT_MAX = 1
ARDUPILOT_POLYGON = 4  # every fence-plan zone: inclusion and exclusion (no-fly) polygons too


def fence_items(polygon: Sequence[tuple[float, float]], home: tuple[float, float],
                autopilot: str, exclusions: Sequence[NoFlyZone] = ()
                ) -> tuple[list[tuple[float, float]], list[ItemFields]]:
    """The lat/lon of each ENU vertex of ``polygon`` (m about ``home``, lat/lon degrees) as
    ``autopilot`` projects its local frame, and the fence plan's MISSION_ITEM_INT fields:
    the polygon as the inclusion zone, then each polygon of ``exclusions`` as a no-fly
    zone, then each circle of them."""
    def run(corners: Sequence[tuple[float, float]], command: int
            ) -> tuple[list[tuple[float, float]], list[ItemFields]]:
        geo = [frames.local_to_geodetic(x, y, home[0], home[1], autopilot) for x, y in corners]
        n = float(len(geo))
        return geo, [(mavlink.MAV_FRAME_GLOBAL, command, 0, 1, n, 0.0, 0.0, 0.0,
                      round(lat * 1e7), round(lon * 1e7), 0.0) for lat, lon in geo]

    geo, items = run(polygon, mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION)
    circles = [zone for zone in exclusions if isinstance(zone, NoFlyCircle)]
    for zone in exclusions:
        if not isinstance(zone, NoFlyCircle):
            items += run(zone, mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION)[1]
    for circle in circles:
        lat, lon = frames.local_to_geodetic(circle.x, circle.y, home[0], home[1], autopilot)
        items.append((mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
                      0, 1, float(circle.radius), 0.0, 0.0, 0.0,
                      round(lat * 1e7), round(lon * 1e7), 0.0))
    return geo, items


# The vehicle's own fence items that the upload keeps, and those it replaces.
_KEPT = {
    mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION: "exclusion",
    mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION: "exclusion",
    mavlink.MAV_CMD_NAV_FENCE_RETURN_POINT: "return point",
}
_POLYGON_VERTICES = {mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                     mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION}


def kept_from_vehicle(items: Sequence[ItemFields]) -> tuple[list[ItemFields], str]:
    """The items of the vehicle's fence plan ``items`` to upload again (exclusion polygons
    and circles, the return point, in their order: a polygon's vertices stay one run), and a
    line saying what was kept and replaced."""
    kept = [item for item in items if item[1] in _KEPT]
    kept_zones = _zones(kept)
    replaced = _zones([item for item in items if item[1] not in _KEPT])
    if not items:
        return [], "the vehicle had no fence plan"
    parts = []
    if kept_zones:
        parts.append(f"kept the vehicle's {_count(kept_zones, 'exclusion zone')}")
    if any(item[1] == mavlink.MAV_CMD_NAV_FENCE_RETURN_POINT for item in kept):
        parts.append("kept its fence return point")
    if replaced:
        parts.append(f"replaced its {_count(replaced, 'inclusion zone')} by the operating area")
    return kept, "; ".join(parts)


def _zones(items: Sequence[ItemFields]) -> int:
    """Zones among fence items: one per circle, one per run of param1 polygon vertices."""
    zones = left = 0
    for item in items:
        if item[1] in _POLYGON_VERTICES:
            if left <= 0:
                zones, left = zones + 1, int(item[4])
            left -= 1
        elif item[1] != mavlink.MAV_CMD_NAV_FENCE_RETURN_POINT:
            zones, left = zones + 1, 0
    return zones


def _count(n: int, what: str) -> str:
    return f"{n} {what}{'' if n == 1 else 's'}"


# The parameter holding what the autopilot does on a breach, and its values' meaning
# (ArduPilot AC_Fence FENCE_ACTION; PX4 GF_ACTION, geofence_params.c).
BREACH_ACTION = {"ardupilot": "FENCE_ACTION", "px4": "GF_ACTION"}
_ACTIONS = {
    "ardupilot": {0: "report only", 1: "RTL or land", 2: "land", 3: "SmartRTL, RTL or land",
                  4: "brake or land", 5: "SmartRTL or land"},
    "px4": {0: "none", 1: "warning only", 2: "Hold", 3: "Return", 4: "terminate", 5: "Land"},
}


def describe_action(autopilot: str, value: int) -> str:
    """``FENCE_ACTION 1 (RTL or land) on a breach``; a warning for an action that does not
    keep the vehicle in."""
    param = BREACH_ACTION.get(autopilot, "FENCE_ACTION")
    name = _ACTIONS.get(autopilot, _ACTIONS["ardupilot"]).get(value, "unknown")
    text = f"{param} {value} ({name}) on a breach"
    if (autopilot == "px4" and value <= 1) or (autopilot != "px4" and value == 0):
        text += f": the autopilot will not act; set {param} on it to have it keep the area"
    return text


def ardupilot_fence_type(max_altitude: float | None) -> int:
    return ARDUPILOT_POLYGON | (ARDUPILOT_ALT_MAX if max_altitude is not None else 0)


@dataclass
class FenceUpload:
    """The operating area sent to the autopilot as its geofence; ``handle`` follows it."""

    vertices: int
    max_altitude: float | None
    handle: Handle
    zones: int = 0  # the mission's no-fly zones sent as exclusion polygons and circles
    circles: int = 0  # the ones of them sent as exclusion circles
    polygon: list[tuple[float, float]] = field(default_factory=list)  # lat, lon degrees
    enabled: str = ""  # how it was enabled, e.g. "FENCE_TYPE 5, MAV_CMD_DO_FENCE_ENABLE"
    action: tuple[str, int] | None = None  # the breach action parameter and its value
    vehicle_fence: str = ""  # what of the vehicle's own fence plan was kept or replaced
    # What the upload changed, to restore after the flight (Driver.restore_fence): the
    # vehicle's fence plan as downloaded, each parameter's value and type before it was set,
    # ArduPilot's FENCE_ENABLE; ``restore`` follows the restore once started.
    vehicle_items: list[ItemFields] = field(default_factory=list)
    before: dict[str, tuple[float, int]] = field(default_factory=dict)
    enable_before: int | None = None
    restore: Handle | None = None

    @property
    def uploaded(self) -> bool:
        return self.handle.status is CommandStatus.ACCEPTED

    def describe(self) -> str:
        ceiling = (f", ceiling {self.max_altitude:g} m above home"
                   if self.max_altitude is not None else ", no ceiling")
        if self.uploaded:
            zones = (f", {_count(self.zones, 'no-fly zone')} ({self._zone_kinds()})"
                     if self.zones else "")
            return (f"geofence uploaded to the autopilot: inclusion polygon of "
                    f"{self.vertices} vertices{zones}{ceiling}; {self.vehicle_fence}; "
                    f"{self.enabled}")
        return f"geofence upload failed ({self.handle.status.value}): {self.handle.reason}"

    def _zone_kinds(self) -> str:
        polygons = self.zones - self.circles
        if not self.circles:
            return "exclusion polygons"
        if not polygons:
            return "exclusion circles"
        return (f"{_count(polygons, 'exclusion polygon')}, "
                f"{_count(self.circles, 'exclusion circle')}")

    def describe_restore(self) -> str:
        """One line on how the vehicle's own geofence was put back (after the flight)."""
        if self.restore is None:
            return "geofence not restored on the autopilot: the mission's stays in force"
        if self.restore.status is not CommandStatus.ACCEPTED:
            return (f"geofence not restored on the autopilot ({self.restore.status.value}): "
                    f"{self.restore.reason}; the mission's may still be in force")
        params = ", ".join(f"{name} {value:g}" for name, (value, _) in self.before.items())
        zones = _zones(self.vehicle_items)
        plan = f"its fence plan ({_count(zones, 'zone')})" if zones else "its empty fence plan"
        text = (f"the vehicle's geofence restored on the autopilot: {plan}"
                + (f", {params}" if params else ""))
        if self.enable_before is not None:
            text += f", fences {'enabled' if self.enable_before else 'disabled'} as FENCE_ENABLE"
        return text

    def as_dict(self) -> dict[str, Any]:
        return {"status": self.handle.status.value, "reason": self.handle.reason,
                "vertices": self.vertices, "max_altitude": self.max_altitude,
                **({"no_fly_zones": self.zones} if self.zones else {}),
                **({"no_fly_circles": self.circles} if self.circles else {}),
                "polygon": [[frames.Degrees(lat), frames.Degrees(lon)]
                            for lat, lon in self.polygon],
                "enabled": self.enabled, "vehicle_fence": self.vehicle_fence,
                "action": None if self.action is None else {self.action[0]: self.action[1]},
                "text": self.describe()}
