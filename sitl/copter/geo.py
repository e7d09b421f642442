"""The simulator's own frame conversions: local ENU <-> MAVLink NED and geodetic.

The SITL is a separate vehicle, so it keeps its own copy of these (the autonomy's driver has
its own, at its boundary). Each personality projects latitude and longitude as its autopilot
does, so a lat/lon target is flown to where that autopilot's GPS would read it: ArduPilot
scales degrees flat about the mid latitude (``Location::offset``, ``get_distance_NE``), PX4
uses an azimuthal equidistant projection about home (``map_projection``). The two differ by
about 0.1-0.2 % of the distance from home.
"""

from __future__ import annotations

import math
from collections.abc import Callable

# ArduPilot's RADIUS_OF_EARTH (m), behind its LOCATION_SCALING_FACTOR.
EARTH_RADIUS = 6378100.0
# PX4's CONSTANTS_RADIUS_OF_EARTH (m).
PX4_EARTH_RADIUS = 6371000.0


def enu_to_ned(e: float, n: float, u: float) -> tuple[float, float, float]:
    """ENU (east, north, up) -> NED (north, east, down)."""
    return (n, e, -u)


def ned_to_enu(n: float, e: float, d: float) -> tuple[float, float, float]:
    """NED (north, east, down) -> ENU (east, north, up)."""
    return (e, n, -d)


def heading_to_enu_yaw(heading: float) -> float:
    """MAVLink heading (rad clockwise from north) -> ENU yaw (rad counter-clockwise from east)."""
    return (math.pi / 2.0 - heading + math.pi) % (2.0 * math.pi) - math.pi


def _wrap_lon(lon: float) -> float:
    return (lon + 180.0) % 360.0 - 180.0


class LocalToGlobal:
    """ArduPilot's projection: local ENU metres around home <-> (lat deg, lon deg), degrees
    scaled flat with the cosine of the mid latitude (never below 0.01, as ArduPilot's
    ``longitude_scale``)."""

    def __init__(self, lat: float, lon: float) -> None:
        self.lat0 = lat
        self.lon0 = lon
        self._m_per_deg = math.radians(1.0) * EARTH_RADIUS

    def _lon_scale(self, lat: float) -> float:
        return max(0.01, math.cos(math.radians((lat + self.lat0) / 2.0)))

    def __call__(self, east: float, north: float) -> tuple[float, float]:
        lat = self.lat0 + north / self._m_per_deg
        return lat, _wrap_lon(self.lon0 + east / (self._m_per_deg * self._lon_scale(lat)))

    def to_local(self, lat: float, lon: float) -> tuple[float, float]:
        """(lat deg, lon deg) -> local (east, north) metres around home; the inverse of
        calling the object."""
        east = _wrap_lon(lon - self.lon0) * self._m_per_deg * self._lon_scale(lat)
        return east, (lat - self.lat0) * self._m_per_deg


class AzimuthalEquidistant:
    """PX4's projection (``map_projection_project`` / ``reproject``) about home."""

    def __init__(self, lat: float, lon: float) -> None:
        self.lat0 = lat
        self.lon0 = lon
        self._phi0 = math.radians(lat)
        self._lam0 = math.radians(lon)

    def __call__(self, east: float, north: float) -> tuple[float, float]:
        x, y = north / PX4_EARTH_RADIUS, east / PX4_EARTH_RADIUS
        c = math.hypot(x, y)
        if c == 0.0:
            return self.lat0, self.lon0
        sin_c, cos_c = math.sin(c), math.cos(c)
        sin0, cos0 = math.sin(self._phi0), math.cos(self._phi0)
        phi = math.asin(max(-1.0, min(1.0, cos_c * sin0 + x * sin_c * cos0 / c)))
        lam = self._lam0 + math.atan2(y * sin_c, c * cos0 * cos_c - x * sin0 * sin_c)
        return math.degrees(phi), _wrap_lon(math.degrees(lam))

    def to_local(self, lat: float, lon: float) -> tuple[float, float]:
        phi, d_lam = math.radians(lat), math.radians(lon) - self._lam0
        sin0, cos0 = math.sin(self._phi0), math.cos(self._phi0)
        arg = sin0 * math.sin(phi) + cos0 * math.cos(phi) * math.cos(d_lam)
        c = math.acos(max(-1.0, min(1.0, arg)))
        k = 1.0 if abs(c) < 1e-12 else c / math.sin(c)
        north = k * (cos0 * math.sin(phi) - sin0 * math.cos(phi) * math.cos(d_lam))
        east = k * math.cos(phi) * math.sin(d_lam)
        return east * PX4_EARTH_RADIUS, north * PX4_EARTH_RADIUS


PROJECTIONS = {"ardupilot": LocalToGlobal, "px4": AzimuthalEquidistant}


# Altitude references of MAVLink's global frames.
_AMSL_FRAMES = frozenset({0, 5})  # MAV_FRAME_GLOBAL, MAV_FRAME_GLOBAL_INT
_RELATIVE_FRAMES = frozenset({3, 6})  # MAV_FRAME_GLOBAL_RELATIVE_ALT(_INT): above home
_TERRAIN_FRAMES = frozenset({10, 11})  # MAV_FRAME_GLOBAL_TERRAIN_ALT(_INT): above the ground


class GeoFrame:
    """Global positions (lat, lon, altitude in one of MAVLink's global frames) <-> local ENU.

    Args:
        lat, lon: the local frame's origin (home at boot), degrees; alt: its ground altitude
            AMSL, m.
        home_z: ENU z of the ground there (the terrain height), m.
        height: function (x, y) -> terrain height (ENU z, m), for terrain-relative frames.
        autopilot: whose projection to use ("ardupilot" or "px4").
    """

    def __init__(self, lat: float, lon: float, alt: float, home_z: float,
                 height: Callable[[float, float], float], autopilot: str = "ardupilot") -> None:
        self.to_global = PROJECTIONS[autopilot](lat, lon)
        self.home_alt = alt
        self.home_z = home_z
        # ENU z of the current home, the zero of MAV_FRAME_GLOBAL_RELATIVE_ALT (moves with
        # home; ``home_alt`` and ``home_z`` stay the local frame's origin).
        self.relative_z = home_z
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
            z = alt + self.relative_z
        else:
            z = alt + self.height(x, y)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return None
        return (x, y, z)
