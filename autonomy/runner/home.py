"""Which home a live flight's lat/lon waypoints are converted about (DESIGN.md section 6).

On a live link the vehicle's frame is about the home it reports (HOME_POSITION): ENU
waypoints are relative to it, and lat/lon waypoints are converted about it, so that they are
flown to their lat/lon. A mission file's ``home`` only places the embedded SITL and its
terrain. When the file gives a home that disagrees with the vehicle's by more than the
tolerances, the flight refuses to start unless ``vehicle.home_from`` (``--home-from``) says
which to fly by. A mission over an elevation model with a coordinate system and no ``home``
has the model's position as its home (the simulated ground lies there on the Earth), and it
is checked the same way: a vehicle elsewhere would see that ground under it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from autonomy.config import Mission, geodetic_to_enu
from autonomy.errors import UserError
from autonomy.vehicle.frames import geodetic

Geo = tuple[float, float, float]  # lat deg, lon deg, alt m AMSL


class HomeMismatch(UserError):
    """The file's home and the vehicle's disagree and no option says which to fly by.

    ``result`` is the flight's :class:`~autonomy.runner.FlightResult` (outputs written) once
    :func:`autonomy.runner.fly` re-raises it.
    """

    result: Any = None


@dataclass(frozen=True)
class HomeChoice:
    """The home a live flight flies by, and how the two homes compare."""

    used: str  # "vehicle" or "file"
    vehicle: Geo
    file: Geo | None  # None when the mission (file or elevation model) gives no home
    distance: float | None  # m horizontally between the two homes
    altitude_difference: float | None  # m, vehicle minus file
    agree: bool
    file_source: str = "mission file"  # or "elevation model": where ``file`` comes from

    @property
    def lat_lon(self) -> tuple[float, float]:
        """(lat, lon) that lat/lon waypoints are converted about."""
        home = self.file if self.used == "file" and self.file is not None else self.vehicle
        return home[0], home[1]

    def whose_home(self) -> str:
        """The home flown by, in words: "the vehicle's home" or "the file's home"."""
        if self.used == "file" and self.file is not None:
            return f"the {_whose(self.file_source)} home"
        return "the vehicle's home"

    def as_dict(self) -> dict[str, Any]:
        return {
            "used": self.used, "vehicle": geodetic(self.vehicle),
            "file": None if self.file is None else geodetic(self.file),
            "distance": self.distance, "altitude_difference": self.altitude_difference,
            "agree": self.agree, "file_source": self.file_source,
        }

    def describe(self) -> str:
        """One console line about the homes."""
        where = f"vehicle home {_geo(self.vehicle)}"
        if self.file is None:
            return f"{where}; the mission file gives no home: flying by the vehicle's"
        apart = (f"{self.distance:.1f} m from the {_whose(self.file_source)} home "
                 f"({self.altitude_difference:+.1f} m)")
        if self.agree:
            return f"{where}, {apart}: the homes agree"
        if self.used == "vehicle":
            return (f"{where}, {apart}: flying by the vehicle's home (lat/lon waypoints are "
                    "flown to their lat/lon)")
        return (f"{where}, {apart}: flying by the {_whose(self.file_source)} home (the "
                "mission as drawn about it, moved to the vehicle's home; lat/lon waypoints are "
                "NOT reached at their lat/lon)")


def _whose(source: str) -> str:
    return "file's" if source == "mission file" else f"{source}'s"


def _geo(home: Geo) -> str:
    return f"{home[0]:.7f}, {home[1]:.7f}, {home[2]:.1f} m"


def compare_homes(vehicle: Geo, file: Geo) -> tuple[float, float]:
    """Horizontal distance (m) and altitude difference (m, vehicle minus file)."""
    east, north = geodetic_to_enu(vehicle[0], vehicle[1], file[0], file[1])
    return math.hypot(east, north), vehicle[2] - file[2]


def choose_home(mission: Mission, vehicle_home: Geo, home_from: str | None = None) -> HomeChoice:
    """The home to fly by, given the one the vehicle reports.

    Args:
        mission: the mission (its ``home`` counts if the file gives one, or an elevation
            model with a coordinate system places it: :attr:`Mission.home_source`).
        vehicle_home: the vehicle's HOME_POSITION (lat, lon, alt AMSL).
        home_from: "vehicle", "file" or None (default ``mission.vehicle.home_from``).

    Raises:
        HomeMismatch: the homes disagree and ``home_from`` is None (the message names both
            homes and how far apart they are).
        UserError: ``home_from`` is "file" but the mission file gives no home.
    """
    config = mission.vehicle
    home_from = home_from or config.home_from
    vehicle_home = tuple(float(v) for v in vehicle_home)  # type: ignore[assignment]
    source = mission.home_source
    if source is None:
        if home_from == "file":
            raise UserError("--home-from file: the mission file gives no home to fly by")
        return HomeChoice("vehicle", vehicle_home, None, None, None, True)
    file_home = (mission.home.lat, mission.home.lon, mission.home.alt)
    distance, height = compare_homes(vehicle_home, file_home)
    agree = distance <= config.home_tolerance and abs(height) <= config.home_altitude_tolerance
    if not agree and home_from is None:
        whose = ("the mission file's home" if source == "mission file" else
                 f"the elevation model's home ({mission.world.path.name} at world.home)")
        raise HomeMismatch(
            f"home mismatch: the vehicle reports home {_geo(vehicle_home)}, {whose} is "
            f"{_geo(file_home)}: {distance:.1f} m apart, {height:+.1f} m in altitude "
            f"(tolerance {config.home_tolerance:g} m, {config.home_altitude_tolerance:g} m); "
            "say which to fly by: --home-from vehicle (lat/lon waypoints flown to their "
            "lat/lon) or --home-from file (the mission as drawn about the file's home, moved "
            "to the vehicle's)"
        )
    return HomeChoice(home_from or "vehicle", vehicle_home, file_home, distance, height, agree,
                      source)
