"""The one place where MAVLink's local NED frame meets the project's local ENU frame.

Everything inside the project is local ENU metres (x east, y north, z up, origin at home);
MAVLink's LOCAL_POSITION_NED and SET_POSITION_TARGET_LOCAL_NED are north-east-down about the
autopilot's local origin (the EKF origin), which may sit ``origin_ned`` metres away from home.
Yaw in NED is clockwise from north; in ENU it is counter-clockwise from east.

    ENU = (y_ned, x_ned, -z_ned)        yaw_enu = pi/2 - yaw_ned   (wrapped to [-pi, pi))

Global coordinates reach the local frame as the autopilot itself projects them
(:func:`geodetic_to_local`), so a lat/lon target is flown to where the autopilot's GPS reads
that lat/lon.
"""

from __future__ import annotations

import math

Vector = tuple[float, float, float]


class Degrees(float):
    """A latitude or longitude in degrees. Reports keep it to 1e-7 degrees (about a
    centimetre, as MAVLink carries it); other floats keep four decimals (0.1 mm), which in
    degrees is 11 m."""


def geodetic(point: tuple[float, float, float]) -> list[float]:
    """``[lat, lon, alt]`` for a report: lat and lon as :class:`Degrees`."""
    return [Degrees(point[0]), Degrees(point[1]), float(point[2])]

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


# Earth radii the autopilots project lat/lon with (m): ArduPilot's RADIUS_OF_EARTH
# (LOCATION_SCALING_FACTOR), PX4's CONSTANTS_RADIUS_OF_EARTH.
ARDUPILOT_EARTH_RADIUS = 6378100.0
PX4_EARTH_RADIUS = 6371000.0


def geodetic_to_local(
    lat: float, lon: float, lat0: float, lon0: float, autopilot: str = "ardupilot"
) -> tuple[float, float]:
    """East and north metres of (lat, lon) from (lat0, lon0) (degrees) as ``autopilot``
    projects them into its local frame, so that a target converted here is flown to where
    the autopilot's own GPS-derived position reads (lat, lon).

    ArduPilot scales degrees flat about the mid latitude (``Location::get_distance_NE``);
    PX4 uses an azimuthal equidistant projection about the reference (``map_projection``).
    The two, and the exact WGS-84 tangent plane, differ by about 0.1-0.2 % of the distance.
    """
    if autopilot == "px4":
        phi, phi0 = math.radians(lat), math.radians(lat0)
        d_lon = math.radians(lon - lon0)
        arg = math.sin(phi0) * math.sin(phi) + math.cos(phi0) * math.cos(phi) * math.cos(d_lon)
        c = math.acos(max(-1.0, min(1.0, arg)))
        k = 1.0 if abs(c) < 1e-12 else c / math.sin(c)
        north = k * (math.cos(phi0) * math.sin(phi) - math.sin(phi0) * math.cos(phi)
                     * math.cos(d_lon)) * PX4_EARTH_RADIUS
        east = k * math.cos(phi) * math.sin(d_lon) * PX4_EARTH_RADIUS
        return east, north
    scale = math.radians(1.0) * ARDUPILOT_EARTH_RADIUS  # m per degree of latitude
    d_lon = (lon - lon0 + 180.0) % 360.0 - 180.0
    east = d_lon * scale * math.cos(math.radians((lat + lat0) / 2.0))
    return east, (lat - lat0) * scale


def local_to_geodetic(
    east: float, north: float, lat0: float, lon0: float, autopilot: str = "ardupilot"
) -> tuple[float, float]:
    """Latitude and longitude (degrees) of the point ``east``, ``north`` metres from
    (lat0, lon0) as ``autopilot`` projects its local frame: the inverse of
    :func:`geodetic_to_local`, so that a point of the flight's ENU frame sent to the
    autopilot as lat/lon (a geofence vertex) is where the autopilot's local frame has it.

    PX4: ``map_projection_reproject`` (azimuthal equidistant); ArduPilot: the flat scaling
    of ``Location::offset`` about the mid latitude, solved for the latitude first.
    """
    if autopilot == "px4":
        x, y = north / PX4_EARTH_RADIUS, east / PX4_EARTH_RADIUS
        c = math.hypot(x, y)
        phi0 = math.radians(lat0)
        if c < 1e-15:
            return lat0, lon0
        sin_c, cos_c = math.sin(c), math.cos(c)
        lat = math.asin(cos_c * math.sin(phi0) + x * sin_c * math.cos(phi0) / c)
        lon = math.radians(lon0) + math.atan2(
            y * sin_c, c * math.cos(phi0) * cos_c - x * math.sin(phi0) * sin_c)
        return math.degrees(lat), (math.degrees(lon) + 180.0) % 360.0 - 180.0
    scale = math.radians(1.0) * ARDUPILOT_EARTH_RADIUS
    lat = lat0 + north / scale
    lon = lon0 + east / (scale * math.cos(math.radians((lat + lat0) / 2.0)))
    return lat, (lon + 180.0) % 360.0 - 180.0
