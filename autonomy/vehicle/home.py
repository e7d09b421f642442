"""The flight's frame, and the vehicle's home moving under it.

Every ENU position the driver reports or flies to is about one origin, the flight's frame.
Until the flight keeps it (:meth:`FlightFrame.keep`, called by the runner when the flight
starts, see docs/how-to/live-flights.md) the origin follows the vehicle's HOME_POSITION, as
before take-off home may still be set or moved. From then on a HOME_POSITION elsewhere
(ArduPilot and PX4 reset home where the vehicle arms; a ground station's MAV_CMD_DO_SET_HOME
moves it at any time) no longer moves the frame: the sites the Landing Site Manager stored and
the waypoints keep pointing at the same ground. Each move is recorded as a :class:`HomeMove`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from autonomy.vehicle import frames

Geo = tuple[float, float, float]  # lat deg, lon deg, alt m AMSL

# m: a home closer than this to the last one recorded is the same home (HOME_POSITION carries
# lat/lon in 1e-7 degrees, about a centimetre, and floats for x, y, z).
HOME_MOVE_TOLERANCE = 0.1


@dataclass(frozen=True)
class HomeMove:
    """The vehicle reported a home away from the one before, while the flight kept its frame."""

    time: float  # clock s when the new home arrived
    previous: Geo  # the home before
    home: Geo  # the new home
    distance: float  # m between the two, in the autopilot's local frame
    position: frames.Vector  # the new home in the flight's ENU frame, m

    def describe(self) -> str:
        lat, lon, alt = self.home
        return (f"home moved by {self.distance:.1f} m (to {lat:.7f}, {lon:.7f}, {alt:.1f} m) "
                f"at {self.time:.1f} s; this flight keeps its frame from takeoff (the new home "
                f"is at ENU {self.position[0]:.1f}, {self.position[1]:.1f}, "
                f"{self.position[2]:.1f} m)")

    def as_dict(self) -> dict:
        return {"t": self.time, "previous": frames.geodetic(self.previous),
                "home": frames.geodetic(self.home),
                "distance": self.distance, "position": list(self.position),
                "text": self.describe()}


class FlightFrame:
    """The origin of the flight's ENU frame: the vehicle's home, followed until kept."""

    def __init__(self) -> None:
        self.origin_ned: frames.Vector = (0.0, 0.0, 0.0)  # in the autopilot's local NED frame
        self.origin: Geo | None = None  # the home the frame is about
        self.kept = False
        self.moves: list[HomeMove] = []
        self._keep_next = False
        self._reference_ned: frames.Vector = (0.0, 0.0, 0.0)  # the last home recorded
        self._reference: Geo | None = None

    def keep(self) -> None:
        """Keep the frame from now on: about the current home, or about the first one the
        vehicle reports when none has come yet."""
        if self.origin is None:
            self._keep_next = True
        else:
            self.kept = True

    def on_home(self, home: Geo, ned: frames.Vector, now: float) -> None:
        """A HOME_POSITION: ``home`` (lat, lon, alt) at ``ned`` (its local NED x, y, z)."""
        if not self.kept:
            self.origin, self.origin_ned = home, ned
            self._reference, self._reference_ned = home, ned
            self.kept = self._keep_next
            return
        distance = math.dist(ned, self._reference_ned)
        if distance <= HOME_MOVE_TOLERANCE:
            return
        assert self._reference is not None
        self.moves.append(HomeMove(now, self._reference, home, distance,
                                   frames.ned_to_enu(*ned, self.origin_ned)))
        self._reference, self._reference_ned = home, ned
