"""Home moving in the embedded SITL, in both personalities, driven by a plain pymavlink client:
MAV_CMD_DO_SET_HOME (a point, or here), its refusals, home reset where the vehicle arms
(unless a ground station locked it), RTL to the current home, and what the move does to the
altitudes reported (relative ones follow home, the local frame stays)."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as C

from sitl import SitlSettings
from tests.sitl.test_sitl_ground_station import (
    ARDUPILOT_GUIDED,
    NAN,
    PX4_LOITER,
    airborne,
    connect,
    last_ack,
    latlon,
    run,
    settle,
)

AUTOPILOTS = ["ardupilot", "px4"]


def set_home(gcs, lat, lon, alt, current=0.0) -> None:
    gcs.command(C.MAV_CMD_DO_SET_HOME, current, 0, 0, 0, lat, lon, alt)


def home_ned(gcs) -> tuple[float, float, float]:
    """The local NED x, y, z of the latest HOME_POSITION."""
    home = gcs.of_type("HOME_POSITION")[-1]
    return home.x, home.y, home.z


def fly_east(sim, gcs, east: float, altitude: float = 10.0) -> None:
    """Reposition to ``east`` m east of the boot home at ``altitude`` m."""
    lat, lon = latlon(sim, east, 0.0)
    gcs.mav.command_int_send(1, 1, C.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, C.MAV_CMD_DO_REPOSITION,
                             0, 0, -1, C.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, NAN,
                             int(lat * 1e7), int(lon * 1e7), altitude)
    assert run(sim, gcs, 40, until=lambda: abs(sim.truth.position[0] - east) < 0.3)


def land_here(sim, gcs) -> None:
    gcs.command(C.MAV_CMD_NAV_LAND)
    assert run(sim, gcs, 60, until=lambda: not sim.truth.armed)


def arm_again(sim, gcs) -> None:
    if sim.personality == "px4":
        gcs.set_mode(PX4_LOITER, px4=True)
    else:
        gcs.set_mode(ARDUPILOT_GUIDED)
    gcs.arm()
    assert run(sim, gcs, 2, until=lambda: sim.truth.armed)
    run(sim, gcs, 0.2)


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_set_home_to_a_point_moves_home_and_rtl_lands_there(autopilot):
    sim, gcs = connect(autopilot)
    airborne(sim, gcs)
    lat, lon = latlon(sim, 30.0, 0.0)
    set_home(gcs, lat, lon, sim.settings.home.alt)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_HOME) == C.MAV_RESULT_ACCEPTED
    home = gcs.of_type("HOME_POSITION")[-1]  # sent at once, not at the next 2 s of the stream
    # COMMAND_LONG carries lat/lon as float32: 4e-6 degrees apart here, about 0.4 m.
    assert (home.latitude, home.longitude) == pytest.approx((lat * 1e7, lon * 1e7), abs=40)
    assert home_ned(gcs) == pytest.approx((0.0, 30.0, 0.0), abs=0.5)
    gcs.command(C.MAV_CMD_NAV_RETURN_TO_LAUNCH)
    assert run(sim, gcs, 120, until=lambda: not sim.truth.armed)
    x, y, z = sim.truth.position
    assert math.hypot(x - 30.0, y) < 1.0 and z == 0.0
    assert not sim.truth.crashed


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
@pytest.mark.parametrize("lat, lon, alt", [
    (91.0, 8.5, 488.0), (-90.5, 8.5, 488.0), (47.4, 181.0, 488.0), (47.4, -200.0, 488.0),
    (NAN, 8.5, 488.0), (47.4, NAN, 488.0), (47.4, 8.5, NAN),
])
def test_set_home_with_a_bad_position_is_denied_and_home_stays(autopilot, lat, lon, alt):
    sim, gcs = connect(autopilot)
    settle(sim, gcs)
    run(sim, gcs, 0.2)
    before = gcs.of_type("HOME_POSITION")[-1]
    set_home(gcs, lat, lon, alt)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_HOME) == C.MAV_RESULT_DENIED
    gcs.command(C.MAV_CMD_GET_HOME_POSITION)
    run(sim, gcs, 0.2)
    after = gcs.of_type("HOME_POSITION")[-1]
    assert (after.latitude, after.longitude, after.altitude) == (
        before.latitude, before.longitude, before.altitude)
    assert sim.server.handler_errors == 0


def test_set_home_before_the_position_estimate_fails():
    sim, gcs = connect()
    set_home(gcs, 0, 0, 0, current=1.0)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_HOME) == C.MAV_RESULT_FAILED


def test_ardupilot_fails_a_home_far_from_its_origin():
    sim, gcs = connect()
    settle(sim, gcs)
    lat, lon = latlon(sim, 60_000.0, 0.0)
    set_home(gcs, lat, lon, 488.0)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_HOME) == C.MAV_RESULT_FAILED


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_set_home_here_and_the_altitudes_it_moves(autopilot):
    sim, gcs = connect(autopilot)
    gcs.set_interval(C.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 10)
    gcs.set_interval(C.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 10)
    airborne(sim, gcs)
    fly_east(sim, gcs, 20.0)
    run(sim, gcs, 0.5)
    local_z = gcs.of_type("LOCAL_POSITION_NED")[-1].z
    relative = gcs.of_type("GLOBAL_POSITION_INT")[-1].relative_alt
    set_home(gcs, NAN, NAN, NAN, current=1.0)
    run(sim, gcs, 0.5)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_HOME) == C.MAV_RESULT_ACCEPTED
    north, east, down = home_ned(gcs)
    assert (north, east) == pytest.approx((0.0, 20.0), abs=0.3)
    assert down == pytest.approx(-10.0, abs=0.4)  # home is where the vehicle is: 10 m up
    # The local frame (the EKF origin) stays; altitudes above home now start at the new home.
    assert gcs.of_type("LOCAL_POSITION_NED")[-1].z == pytest.approx(local_z, abs=0.3)
    assert gcs.of_type("GLOBAL_POSITION_INT")[-1].relative_alt == pytest.approx(
        relative - 10_000, abs=400)


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_arming_moves_home_where_the_vehicle_is_unless_a_ground_station_set_it(autopilot):
    sim, gcs = connect(autopilot)
    airborne(sim, gcs)
    fly_east(sim, gcs, 20.0)
    land_here(sim, gcs)
    assert home_ned(gcs)[:2] == pytest.approx((0.0, 0.0), abs=1e-6)
    arm_again(sim, gcs)
    assert home_ned(gcs) == pytest.approx((0.0, 20.0, 0.0), abs=0.3)

    # A home a ground station set is kept through the next arming.
    lat, lon = latlon(sim, 0.0, 15.0)
    set_home(gcs, lat, lon, sim.settings.home.alt)
    gcs.disarm()
    run(sim, gcs, 0.5)
    assert not sim.truth.armed
    arm_again(sim, gcs)
    assert home_ned(gcs) == pytest.approx((15.0, 0.0, 0.0), abs=0.5)


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_a_scheduled_home_change_is_a_ground_stations_set_home(autopilot):
    settings = SitlSettings(home_change={"at": 5.0, "east": 30.0, "north": -10.0})
    sim, gcs = connect(autopilot, settings=settings)
    run(sim, gcs, 5.5)
    assert home_ned(gcs) == pytest.approx((-10.0, 30.0, 0.0), abs=1e-3)
    assert sim.home_change_result == C.MAV_RESULT_ACCEPTED
