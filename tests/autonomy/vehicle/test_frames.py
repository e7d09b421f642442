"""ENU <-> NED conversion, the single place the two frames meet."""

import math

from hypothesis import given
from hypothesis import strategies as st

from autonomy.vehicle import frames

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
