"""ENU <-> NED conversion, the single place the two frames meet, and lat/lon into the
autopilot's local frame."""

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from autonomy.config import geodetic_to_enu
from autonomy.vehicle import frames
from autonomy.vehicle.frames import geodetic_to_local

finite = st.floats(-1e5, 1e5, allow_nan=False)
angle = st.floats(-10.0, 10.0, allow_nan=False)


@given(finite, finite, finite, finite, finite, finite)
def test_position_round_trip(x, y, z, ox, oy, oz):
    origin = (ox, oy, oz)
    back = frames.ned_to_enu(*frames.enu_to_ned(x, y, z, origin), origin)
    assert all(math.isclose(a, b, abs_tol=1e-6) for a, b in zip(back, (x, y, z), strict=True))


def test_axes_swap_and_z_flips():
    # 10 m north, 3 m east, 5 m down in NED is 3 m east, 10 m north, 5 m below home in ENU.
    assert frames.ned_to_enu(10.0, 3.0, 5.0) == (3.0, 10.0, -5.0)
    assert frames.ned_to_enu_velocity(1.0, 2.0, -0.5) == (2.0, 1.0, 0.5)


def test_home_offset_is_removed():
    # Home 2 m north of the EKF origin and 1 m above it: the vehicle at home reads (0, 0, 0).
    home = (2.0, 0.0, -1.0)
    assert frames.ned_to_enu(2.0, 0.0, -1.0, home) == (0.0, 0.0, 0.0)
    assert frames.ned_to_enu(2.0, 0.0, -11.0, home) == (0.0, 0.0, 10.0)


@given(angle)
def test_yaw_round_trip(yaw):
    back = frames.ned_to_enu_yaw(frames.enu_to_ned_yaw(yaw))
    assert math.isclose(math.cos(back), math.cos(yaw), abs_tol=1e-9)
    assert math.isclose(math.sin(back), math.sin(yaw), abs_tol=1e-9)
    assert -math.pi <= back < math.pi


def test_yaw_north_and_east():
    # Heading north (NED 0) points along ENU +y (pi/2); heading east (NED pi/2) is ENU 0.
    assert math.isclose(frames.ned_to_enu_yaw(0.0), math.pi / 2)
    assert math.isclose(frames.ned_to_enu_yaw(math.pi / 2), 0.0, abs_tol=1e-12)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
@pytest.mark.parametrize("home", [(47.397742, 8.545594), (-35.363262, 149.165237),
                                  (78.22, 15.65), (0.1, 179.99)])
def test_lat_lon_reach_the_local_frame_as_each_autopilot_projects_them(autopilot, home):
    # The embedded SITL projects as the autopilot it imitates; so must the driver.
    from sitl.copter.geo import PROJECTIONS

    to_global = PROJECTIONS[autopilot](*home)
    for east, north in ((400.0, -300.0), (-600.0, 500.0), (3000.0, 2500.0)):
        lat, lon = to_global(east, north)
        x, y = geodetic_to_local(lat, lon, *home, autopilot=autopilot)
        assert math.hypot(x - east, y - north) < 1e-6


def test_the_projections_differ_from_the_exact_tangent_plane():
    # ArduPilot's flat scaling is off the WGS-84 tangent plane by ~0.2 % of the distance.
    home = (47.397742, 8.545594)
    for east, north in ((400.0, -300.0), (-600.0, 500.0)):
        lat, lon = frames_lat_lon(home, east, north)
        ex, ey = geodetic_to_enu(lat, lon, *home)
        assert math.hypot(ex - east, ey - north) > 0.001 * math.hypot(east, north)
    # PX4: an azimuthal equidistant projection on a 6371 km sphere.
    x, y = geodetic_to_local(48.0, 8.0, 47.0, 8.0, autopilot="px4")
    assert x == pytest.approx(0.0, abs=1e-6)
    assert y == pytest.approx(6371000.0 * math.pi / 180.0)


def frames_lat_lon(home, east, north):
    from sitl.copter.geo import LocalToGlobal

    return LocalToGlobal(*home)(east, north)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
@given(east=st.floats(-50_000, 50_000), north=st.floats(-50_000, 50_000),
       lat0=st.floats(-80, 80), lon0=st.floats(-180, 180))
def test_local_to_geodetic_inverts_each_autopilots_projection(autopilot, east, north, lat0,
                                                              lon0):
    lat, lon = frames.local_to_geodetic(east, north, lat0, lon0, autopilot)
    back = geodetic_to_local(lat, lon, lat0, lon0, autopilot)
    assert back == pytest.approx((east, north), abs=1e-4)
