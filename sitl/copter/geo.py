"""The simulator's own frame conversions: local ENU <-> MAVLink NED and geodetic.

The SITL is a separate vehicle, so it keeps its own copy of these (the autonomy's driver has
its own, at its boundary). Flat-earth scaling around home, as ArduPilot does.
"""

from __future__ import annotations

import math
from collections.abc import Callable

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

    def to_local(self, lat: float, lon: float) -> tuple[float, float]:
        """(lat deg, lon deg) -> local (east, north) metres around home; the inverse of
        calling the object."""
        return (
            ((lon - self.lon0 + 180.0) % 360.0 - 180.0) / self._deg_per_m_lon,
            (lat - self.lat0) / self._deg_per_m_lat,
        )


# Altitude references of MAVLink's global frames.
_AMSL_FRAMES = frozenset({0, 5})  # MAV_FRAME_GLOBAL, MAV_FRAME_GLOBAL_INT
_RELATIVE_FRAMES = frozenset({3, 6})  # MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT): above home
_TERRAIN_FRAMES = frozenset({10, 11})  # MAV_FRAME_GLOBAL_TERRAIN_ALT(_INT): above the ground


class GeoFrame:
    """Global positions (lat, lon, altitude in one of MAVLink's global frames) <-> local ENU.

    Args:
        lat, lon: home, degrees; alt: home ground altitude AMSL, m.
        home_z: ENU z of the ground at home (the terrain height there), m.
        height: function (x, y) -> terrain height (ENU z, m), for terrain-relative frames.
    """

    def __init__(self, lat: float, lon: float, alt: float, home_z: float,
                 height: Callable[[float, float], float]) -> None:
        self.to_global = LocalToGlobal(lat, lon)
        self.home_alt = alt
        self.home_z = home_z
        self.height = height

    def to_enu(
        self,
        lat: float | None,
        lon: float | None,
        alt: float | None,
        frame: int,
        current: tuple[float, float, float],
    ) -> tuple[float, float, float] | None:
        """The ENU point of (lat, lon, alt) in ``frame``; a None coordinate keeps the one of
        ``current``. None when the frame is not a global one or a value is not finite."""
        if frame not in _AMSL_FRAMES | _RELATIVE_FRAMES | _TERRAIN_FRAMES:
            return None
        if (lat is None) != (lon is None):
            return None
        if lat is None:
            x, y = current[0], current[1]
        else:
            x, y = self.to_global.to_local(lat, lon)
        if alt is None:
            z = current[2]
        elif frame in _AMSL_FRAMES:
            z = alt - self.home_alt + self.home_z
        elif frame in _RELATIVE_FRAMES:
            z = alt + self.home_z
        else:
            z = alt + self.height(x, y)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return None
        return (x, y, z)
