"""The one place where MAVLink's local NED frame meets the project's local ENU frame.

Everything inside the project is local ENU metres (x east, y north, z up, origin at home);
MAVLink's LOCAL_POSITION_NED and SET_POSITION_TARGET_LOCAL_NED are north-east-down about the
autopilot's local origin (the EKF origin), which may sit ``origin_ned`` metres away from home.
Yaw in NED is clockwise from north; in ENU it is counter-clockwise from east.

    ENU = (y_ned, x_ned, -z_ned)        yaw_enu = pi/2 - yaw_ned   (wrapped to [-pi, pi))
"""

from __future__ import annotations

import math

Vector = tuple[float, float, float]

_ZERO: Vector = (0.0, 0.0, 0.0)


def wrap_angle(angle: float) -> float:
    """``angle`` (rad) wrapped to [-pi, pi)."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def ned_to_enu(x: float, y: float, z: float, origin_ned: Vector = _ZERO) -> Vector:
    """Local NED position (m) -> ENU position (m) relative to the home point ``origin_ned``.

    ``origin_ned`` is home in the autopilot's local NED frame (HOME_POSITION x, y, z).
    """
    return (float(y - origin_ned[1]), float(x - origin_ned[0]), float(origin_ned[2] - z))


def enu_to_ned(x: float, y: float, z: float, origin_ned: Vector = _ZERO) -> Vector:
    """ENU position (m, relative to home) -> local NED position (m); inverse of ned_to_enu."""
    return (float(y + origin_ned[0]), float(x + origin_ned[1]), float(origin_ned[2] - z))


def ned_to_enu_velocity(vx: float, vy: float, vz: float) -> Vector:
    """NED velocity (m/s) -> ENU velocity (m/s)."""
    return (float(vy), float(vx), float(-vz))


def enu_to_ned_velocity(vx: float, vy: float, vz: float) -> Vector:
    """ENU velocity (m/s) -> NED velocity (m/s)."""
    return (float(vy), float(vx), float(-vz))


def ned_to_enu_yaw(yaw_ned: float) -> float:
    """Heading clockwise from north (rad) -> yaw counter-clockwise from east (rad)."""
    return wrap_angle(math.pi / 2.0 - yaw_ned)


def enu_to_ned_yaw(yaw_enu: float) -> float:
    """Yaw counter-clockwise from east (rad) -> heading clockwise from north (rad)."""
    return wrap_angle(math.pi / 2.0 - yaw_enu)
