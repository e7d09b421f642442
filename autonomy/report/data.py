"""What a flight leaves behind for its report: the trace and the end state."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from lsm.area import NoFlyCircle
from lsm.records import LandingSite


@dataclass
class FlightTrace:
    """Samples of the flight, appended once per tick.

    Positions are ground truth from the simulator when there is one, else what the autopilot
    reported (ENU metres); battery is percent (NaN when unknown).
    """

    t: list[float] = field(default_factory=list)
    xyz: list[tuple[float, float, float]] = field(default_factory=list)
    battery: list[float] = field(default_factory=list)
    phases: list[tuple[float, str]] = field(default_factory=list)  # (start time, phase)

    def append(self, t: float, xyz: tuple[float, float, float] | None, battery: float | None):
        if xyz is None:
            return
        self.t.append(t)
        self.xyz.append(xyz)
        self.battery.append(np.nan if battery is None else battery)

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(N,) times s, (N, 3) positions m, (N,) battery %."""
        return (
            np.asarray(self.t, dtype=np.float64),
            np.asarray(self.xyz, dtype=np.float64).reshape(-1, 3),
            np.asarray(self.battery, dtype=np.float64),
        )

    def distance(self) -> float:
        """Path length flown, m (3-D)."""
        _, xyz, _ = self.arrays()
        if len(xyz) < 2:
            return 0.0
        return float(np.linalg.norm(np.diff(xyz, axis=0), axis=1).sum())

    def phase_start(self, *phases: str) -> float | None:
        """Clock time the first of ``phases`` began, or None."""
        return next((t for t, p in self.phases if p in phases), None)

    def mission_end(self) -> float | None:
        """Clock time the mission waypoints ended: the first phase after preflight, takeoff
        and mission (landing phase, search, failsafe ...), or None."""
        started = False
        for t, p in self.phases:
            if p in ("takeoff", "mission"):
                started = True
            elif started and p != "preflight":
                return t
        return None


@dataclass
class FlightData:
    """Everything the summary and the plot are made from.

    ``status`` is the tree's final status ("SUCCESS", "FAILURE", "RUNNING" when stopped by
    the time limit or an interrupt); ``stop_reason`` says why the loop ended.
    """

    mission_name: str
    seed: int
    autopilot: str
    world: str
    detector: str
    trace: FlightTrace
    end_time: float
    status: str
    stop_reason: str
    sites: list[LandingSite]
    ban_zones: list[tuple[float, float, float]]
    chosen_site: LandingSite | None
    touchdown: tuple[float, float, float] | None
    touchdown_time: float | None
    touchdown_speed: float | None
    touchdown_safe: bool | None
    crashed: bool
    crash_reason: str | None
    outcome_hint: str | None
    failure_reason: str | None
    verification_attempts: int
    search_patterns: int
    sites_verified: int
    lsm_counters: dict[str, int]
    perception_counters: dict[str, int]
    lockstep: bool = True  # simulated time (False: a live flight on the vehicle's time)
    chosen_verified: bool | None = None  # the chosen site counted as verified at the end
    energy_wh: float | None = None
    wall_time: float = 0.0
    terrain: Any = None  # sitl.terrain.Terrain or None (flat)
    link: dict[str, Any] | None = None  # the driver's link statistics
    link_lost: str | None = None  # why the flight ended on the link (outcome link_lost)
    home: dict[str, Any] | None = None  # live: the homes compared and the one flown by
    home_moves: list[dict[str, Any]] | None = None  # the vehicle's home moved under the frame
    refused: bool = False  # live: refused before takeoff (the homes disagree)
    interrupted: bool = False  # Ctrl-C ended the flight (its outcome is then aborted)
    weights: Any = None  # lsm.settings.LossWeights of the mission (report.html's loss terms)
    verified_ids: list[int] = field(default_factory=list)  # retained sites counted verified
    extra: dict[str, Any] = field(default_factory=dict)
    collisions: int | None = None  # contacts with raised ground or moving obstacles (lockstep)
    first_collision: dict[str, Any] | None = None  # sitl.terrain.contact.Contact.as_dict()
    geofence: list[tuple[float, float]] | None = None  # the operating area's ENU vertices
    # The no-fly zones: polygons (ENU vertices) and lsm.area.NoFlyCircle, in the file's order.
    geofence_exclude: list[Any] = field(default_factory=list)
    # autonomy.vehicle.fence.FenceUpload.as_dict(): the area sent to the autopilot, if it was
    geofence_upload: dict[str, Any] | None = None


def zone_record(zone: Any) -> list[list[float]] | dict[str, Any]:
    """A no-fly zone as summary.json and report.html list it (ENU m): a polygon as its
    vertices, a circle as ``{"centre": [x, y], "radius": r}``."""
    if isinstance(zone, NoFlyCircle):
        return {"centre": [zone.x, zone.y], "radius": zone.radius}
    return [list(v) for v in zone]
