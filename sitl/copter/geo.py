"""The simulator's own frame conversions: local ENU <-> MAVLink NED and geodetic.

The SITL is a separate vehicle, so it keeps its own copy of these (the autonomy's driver has
its own, at its boundary). Flat-earth scaling around home, as ArduPilot does.
"""

from __future__ import annotations

import math

# ArduPilot's RADIUS_OF_EARTH (m).
EARTH_RADIUS = 6378100.0


def enu_to_ned(e: float, n: float, u: float) -> tuple[float, float, float]:
    """ENU (east, north, up) -> NED (north, east, down)."""
    return (n, e, -u)


def ned_to_enu(n: float, e: float, d: float) -> tuple[float, float, float]:
    """NED (north, east, down) -> ENU (east, north, up)."""
    return (e, n, -d)


def heading_to_enu_yaw(heading: float) -> float:
    """MAVLink heading (rad clockwise from north) -> ENU yaw (rad counter-clockwise from east)."""
    return (math.pi / 2.0 - heading + math.pi) % (2.0 * math.pi) - math.pi


class LocalToGlobal:
    """Local ENU metres around home -> (lat deg, lon deg)."""

    def __init__(self, lat: float, lon: float) -> None:
        self.lat0 = lat
        self.lon0 = lon
        self._deg_per_m_lat = math.degrees(1.0 / EARTH_RADIUS)
        self._deg_per_m_lon = math.degrees(1.0 / (EARTH_RADIUS * math.cos(math.radians(lat))))

    def __call__(self, east: float, north: float) -> tuple[float, float]:
        return (
            self.lat0 + north * self._deg_per_m_lat,
            self.lon0 + east * self._deg_per_m_lon,
        )
