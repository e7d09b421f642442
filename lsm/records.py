"""Records exchanged with the Landing Site Manager.

Positions are local ENU metres (origin at home, z up); altitudes are metres; timestamps are
seconds of the injected clock (simulated time in lockstep runs).
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class SiteObservation:
    """One candidate landing site as a detector reported it.

    Attributes:
        x, y, z: site centre, ENU metres (z is the ground height at the site).
        roughness: normalised roughness in [0, 1] (0 = perfectly flat).
        uncertainty: normalised uncertainty in [0, 1] (0 = certain).
        size: metric radius of the largest landable circle around the site, metres, >= 0.
        obstacle_altitude: ENU z of the highest terrain to clear around the site, metres.
        observation_altitude: vertical distance drone -> site when observed, metres, >= 0.
        timestamp: clock seconds of the observation.
        source: which detector or sensor produced it (free text, e.g. ``"sfm"``).
    """

    x: float
    y: float
    z: float
    roughness: float
    uncertainty: float
    size: float
    obstacle_altitude: float
    observation_altitude: float
    timestamp: float = 0.0
    source: str = ""

    @property
    def position(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.z)


@dataclass(frozen=True, slots=True)
class LandingSite:
    """A retained landing site: the last trusted properties plus bookkeeping.

    ``verification_altitude`` is the smallest observation altitude at which the site was
    (re-)detected; a site is verified when it is at most the mission's verification altitude
    plus a tolerance. ``loss`` is the loss at the drone position of the ranking that produced
    this record (NaN when the record did not come from a ranking).
    """

    id: int
    x: float
    y: float
    z: float
    roughness: float
    uncertainty: float
    size: float
    obstacle_altitude: float
    verification_altitude: float
    first_seen: float
    last_seen: float
    detection_count: int
    source: str = ""
    loss: float = float("nan")

    @property
    def position(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.z)
