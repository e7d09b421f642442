"""The geofence, enforced as each autopilot does: an uploaded fence plan (inclusion and
exclusion polygons and circles) and the autopilot's own limits, breaches reported in
STATUSTEXT, SYS_STATUS and (ArduPilot) FENCE_STATUS and answered with the configured action,
arming refused outside. Driven over the in-memory link by a plain pymavlink client."""

from __future__ import annotations

import math
import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.copter.fence import Zones, fence_names, zones_from_plan
from sitl.copter.geo import AzimuthalEquidistant, LocalToGlobal
from sitl.copter.mission import MissionItem
from tests.sitl.test_sitl_ground_station import airborne, connect, run

C = mavlink
DT = 0.05
NAN = math.nan
GUIDED, LOITER, RTL, LAND = 4, 5, 6, 9
PX4_LOITER = (4 << 16) | (3 << 24)
PX4_RTL = (4 << 16) | (5 << 24)
FENCE = C.MAV_MISSION_TYPE_FENCE
GEOFENCE = C.MAV_SYS_STATUS_GEOFENCE
INT8, INT32, REAL32 = C.MAV_PARAM_TYPE_INT8, C.MAV_PARAM_TYPE_INT32, C.MAV_PARAM_TYPE_REAL32


def px4_int(value: int) -> float:
    """A PX4 int32 parameter as PARAM_SET carries it (its bytes in the float)."""
    return struct.unpack("<f", struct.pack("<i", value))[0]


def said(gcs, text: str) -> bool:
    """``text`` arrived in a STATUSTEXT (whose 50 characters cut PX4's longer lines)."""
    return text[:50] in gcs.texts()


def latlon(sim, east, north):
    home = sim.settings.home
    project = LocalToGlobal if sim.personality == "ardupilot" else AzimuthalEquidistant
    return project(home.lat, home.lon)(east, north)


def square(sim, gcs, half: float, command: int, center=(0.0, 0.0), start: int = 0) -> list:
    """The four vertex items of a square fence polygon ``half`` m either side of ``center``."""
    cx, cy = center
    corners = [(cx - half, cy - half), (cx + half, cy - half), (cx + half, cy + half),
               (cx - half, cy + half)]
    return [gcs.mission_item(start + i, command, *latlon(sim, e, n), 0, frame=C.MAV_FRAME_GLOBAL,
                             params=(4, 0, 0, 0), mission_type=FENCE)
            for i, (e, n) in enumerate(corners)]


def upload_fence(sim, gcs, items) -> None:
    gcs.upload_mission(items, FENCE)
    assert run(sim, gcs, 5, until=lambda: any(
        m.mission_type == FENCE for m in gcs.of_type("MISSION_ACK")))
    assert gcs.of_type("MISSION_ACK")[-1].type == C.MAV_MISSION_ACCEPTED


def fly_east(sim, gcs, speed=5.0) -> None:
    """A guided velocity target east, refreshed (ArduPilot GUIDED, PX4 OFFBOARD)."""
    gcs.velocity_ned(0, speed, 0)


# ------------------------------------------------------------------------- the zones
def test_polygons_and_circles_from_a_fence_plan():
    item = MissionItem
    v = C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
    x = C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    plan = [item(v, 0, 4, x=-10, y=-10), item(v, 0, 4, x=10, y=-10), item(v, 0, 4, x=10, y=10),
            item(v, 0, 4, x=-10, y=10),
            item(x, 0, 3, x=0, y=0), item(x, 0, 3, x=2, y=0), item(x, 0, 3, x=0, y=2),
            item(C.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 0, 1.0, x=-5, y=-5)]
    zones = zones_from_plan(plan, lambda lat, lon: (lat, lon))  # degrees taken as metres
    assert len(zones.inclusion) == 1 and len(zones.exclusion) == 1
    assert len(zones.exclusion_circles) == 1
    assert not zones.breached_intersection(5, 5)
    assert zones.breached_intersection(11, 0)  # outside the inclusion
    assert zones.breached_intersection(0.5, 0.5)  # inside the triangle excluded
    assert zones.breached_intersection(-5.5, -5)  # inside the excluded circle
    assert zones.distance_outside(13, 0) == pytest.approx(3.0)
    assert not Zones()


def test_union_of_inclusion_zones_is_px4s():
    v = C.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
    plan = [MissionItem(v, 0, 5.0, x=0, y=0), MissionItem(v, 0, 5.0, x=20, y=0)]
    zones = zones_from_plan(plan, lambda lat, lon: (lat, lon))
    assert not zones.breached_union(20, 0)  # inside one of them is enough for PX4
    assert zones.breached_intersection(20, 0)  # ArduPilot wants every inclusion zone
    assert zones.breached_union(10, 0)


def test_fence_names_as_ardupilot_says_them():
    assert fence_names(4) == "Polygon fence"
    assert fence_names(1 | 2) == "Max Alt and Circle fences"
    assert fence_names(1 | 2 | 4) == "Max Alt, Circle and Polygon fences"


# ------------------------------------------------------------------------- ArduPilot
def test_ardupilot_defaults_leave_the_fence_off():
    sim, gcs = connect()
    gcs.param_read("FENCE_ENABLE")
    gcs.param_read("FENCE_ACTION")
    gcs.param_read("FENCE_TYPE")
    gcs.set_interval(C.MAVLINK_MSG_ID_SYS_STATUS, 2)
    gcs.set_interval(C.MAVLINK_MSG_ID_FENCE_STATUS, 2)
    run(sim, gcs, 2)
    assert gcs.params() == {"FENCE_ENABLE": 0.0, "FENCE_ACTION": 1.0, "FENCE_TYPE": 7.0}
    status = gcs.last["SYS_STATUS"]
    # AC_Fence::present: the circle and the ceiling are configured, not enabled, not breached
    assert status.onboard_control_sensors_present & GEOFENCE
    assert not status.onboard_control_sensors_enabled & GEOFENCE
    assert status.onboard_control_sensors_health & GEOFENCE
    assert "FENCE_STATUS" not in gcs.last  # sent only while a fence is enabled


def test_ardupilot_polygon_breach_returns_to_launch():
    sim, gcs = connect()
    upload_fence(sim, gcs, square(sim, gcs, 30.0, C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION))
    gcs.param_set("FENCE_ENABLE", 1, INT8)
    gcs.set_interval(C.MAVLINK_MSG_ID_SYS_STATUS, 5)
    gcs.set_interval(C.MAVLINK_MSG_ID_FENCE_STATUS, 5)
    airborne(sim, gcs)
    run(sim, gcs, 0.5)
    assert gcs.last["SYS_STATUS"].onboard_control_sensors_enabled & GEOFENCE
    assert gcs.last["FENCE_STATUS"].breach_status == 0
    # A position target beyond the fence is refused (ModeGuided::set_destination), ...
    gcs.goto_ned(0, 60, -10)
    run(sim, gcs, 3)
    assert sim.truth.position[0] < 1.0 and sim.autopilot.mode == "GUIDED"
    # ... and a DO_REPOSITION there fails.
    lat, lon = latlon(sim, 60, 0)
    gcs.command(C.MAV_CMD_DO_REPOSITION, -1, 1, 0, NAN, lat, lon, sim.settings.home.alt + 10)
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_DO_REPOSITION)[-1] == C.MAV_RESULT_FAILED
    # A velocity target is not checked: the vehicle crosses, and the fence sends it home.
    assert run(sim, gcs, 30, until=lambda: fly_east(sim, gcs) or sim.autopilot.mode == "RTL")
    assert 30.0 <= sim.truth.position[0] < 32.0
    assert said(gcs, "Polygon fence breached")
    run(sim, gcs, 0.5)
    status = gcs.last["FENCE_STATUS"]
    assert (status.breach_status, status.breach_count, status.breach_type) == (
        1, 1, C.FENCE_BREACH_BOUNDARY)
    assert status.breach_time == pytest.approx(sim.time * 1000, abs=1500)
    assert not gcs.last["SYS_STATUS"].onboard_control_sensors_health & GEOFENCE
    # Back inside on its way home: the breach clears, the count stays.
    assert run(sim, gcs, 30, until=lambda: "Fence breach cleared" in gcs.texts())
    run(sim, gcs, 0.5)
    assert gcs.last["FENCE_STATUS"].breach_status == 0
    assert gcs.last["FENCE_STATUS"].breach_count == 1
    assert gcs.last["SYS_STATUS"].onboard_control_sensors_health & GEOFENCE
    assert run(sim, gcs, 60, until=lambda: not sim.autopilot.armed)
    assert math.hypot(*sim.truth.position[:2]) < 1.5


def test_ardupilot_exclusion_zone_lands_with_fence_action_2():
    sim, gcs = connect()
    upload_fence(sim, gcs, square(sim, gcs, 5.0, C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION,
                                  center=(20.0, 0.0)))
    gcs.param_set("FENCE_ACTION", 2, INT8)  # always land
    gcs.command(C.MAV_CMD_DO_FENCE_ENABLE, 1)
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_DO_FENCE_ENABLE)[-1] == C.MAV_RESULT_ACCEPTED
    airborne(sim, gcs)
    assert run(sim, gcs, 20, until=lambda: fly_east(sim, gcs) or sim.autopilot.mode == "LAND")
    assert 14.0 <= sim.truth.position[0] < 17.0
    assert said(gcs, "Polygon fence breached")


def test_ardupilot_ceiling_breach_and_report_only():
    sim, gcs = connect()
    gcs.param_set("FENCE_ALT_MAX", 15, REAL32)
    gcs.param_set("FENCE_ACTION", 0, INT8)  # report only
    gcs.param_set("FENCE_ENABLE", 1, INT8)
    gcs.set_interval(C.MAVLINK_MSG_ID_FENCE_STATUS, 5)
    airborne(sim, gcs)
    gcs.goto_ned(0, 0, -20)  # above the ceiling: refused
    run(sim, gcs, 5)
    assert sim.truth.position[2] < 11.0
    assert run(sim, gcs, 10, until=lambda: gcs.velocity_ned(0, 0, -2) or sim.truth.position[2]
                > 15.5)
    run(sim, gcs, 0.5)
    assert said(gcs, "Max Alt fence breached")
    assert gcs.last["FENCE_STATUS"].breach_type == C.FENCE_BREACH_MAXALT
    assert sim.autopilot.mode == "GUIDED"  # report only


def test_ardupilot_refuses_to_arm_outside_the_fence():
    sim, gcs = connect()
    upload_fence(sim, gcs, square(sim, gcs, 10.0, C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                                  center=(50.0, 0.0)))
    gcs.param_set("FENCE_ENABLE", 1, INT8)
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.set_mode(GUIDED)
    gcs.arm()
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == C.MAV_RESULT_FAILED
    assert said(gcs, "PreArm: Vehicle breaching Polygon fence")
    gcs.command(C.MAV_CMD_DO_FENCE_ENABLE, 0)
    gcs.arm()
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == C.MAV_RESULT_ACCEPTED


# ------------------------------------------------------------------------- PX4
def px4_offboard(sim, gcs) -> None:
    for _ in range(10):
        gcs.velocity_ned(0, 0, 0)
        run(sim, gcs, 0.1)
    gcs.set_mode(6 << 16, px4=True)
    run(sim, gcs, 0.2)
    assert sim.autopilot.mode == "OFFBOARD"


@pytest.mark.parametrize(("action", "mode"), [(2, "AUTO.LOITER"), (3, "AUTO.RTL")])
def test_px4_geofence_breach_holds_or_returns(action, mode):
    sim, gcs = connect("px4")
    upload_fence(sim, gcs, square(sim, gcs, 30.0, C.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION))
    gcs.param_set("GF_ACTION", px4_int(action), INT32)
    airborne(sim, gcs)
    px4_offboard(sim, gcs)
    assert run(sim, gcs, 30, until=lambda: fly_east(sim, gcs) or sim.autopilot.mode == mode)
    assert 30.0 <= sim.truth.position[0] < 33.0
    assert said(gcs, "Geofence violation: approaching or outside geofence")
    # PX4 reports no geofence in SYS_STATUS
    assert not gcs.last["SYS_STATUS"].onboard_control_sensors_present & GEOFENCE


def test_px4_max_distance_and_warning_only():
    sim, gcs = connect("px4")
    gcs.param_set("GF_MAX_HOR_DIST", 20, REAL32)
    gcs.param_set("GF_ACTION", px4_int(1), INT32)  # warning
    airborne(sim, gcs)
    px4_offboard(sim, gcs)
    assert run(sim, gcs, 30, until=lambda: fly_east(sim, gcs) or sim.truth.position[0] > 25)
    assert said(gcs, "Geofence violation: exceeding maximum distance to Home")
    assert sim.autopilot.mode == "OFFBOARD"


def test_px4_without_a_fence_does_nothing_by_default():
    sim, gcs = connect("px4")
    airborne(sim, gcs, altitude=5.0)
    px4_offboard(sim, gcs)
    run(sim, gcs, 20, until=lambda: fly_east(sim, gcs) and False)
    assert sim.truth.position[0] > 50 and sim.autopilot.mode == "OFFBOARD"
    assert not [t for t in gcs.texts() if "Geofence" in t]


def test_px4_refuses_to_arm_outside_the_fence():
    sim, gcs = connect("px4")
    upload_fence(sim, gcs, [gcs.mission_item(0, C.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION,
                                             *latlon(sim, 0, 0), 0, frame=C.MAV_FRAME_GLOBAL,
                                             params=(10, 0, 0, 0), mission_type=FENCE)])
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.arm()
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == C.MAV_RESULT_TEMPORARILY_REJECTED
    assert said(gcs, "Geofence violation: approaching or outside geofence")
    gcs.param_set("GF_ACTION", px4_int(0), INT32)
    gcs.arm()
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == C.MAV_RESULT_ACCEPTED


def test_ardupilot_circle_is_about_home_where_a_ground_station_set_it():
    sim, gcs = connect()
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    lat, lon = latlon(sim, 40.0, 0.0)
    gcs.command(C.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, lat, lon, sim.settings.home.alt)
    gcs.param_set("FENCE_RADIUS", 30, REAL32)
    gcs.param_set("FENCE_ENABLE", 1, INT8)
    gcs.set_mode(GUIDED)
    gcs.arm()
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_DO_SET_HOME)[-1] == C.MAV_RESULT_ACCEPTED
    assert gcs.acks(C.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == C.MAV_RESULT_FAILED
    assert said(gcs, "PreArm: Vehicle breaching Circle fence")  # 40 m from home
