"""Validated settings of the landing behaviours and the mission plan (pydantic v2).

Positions are local ENU metres (origin at home, z up, z = altitude above home); durations are
seconds of the injected clock; battery levels are percent. Nothing here is an angle, so YAML
needs no degree conversion for these models.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, InstanceOf, model_validator

from behaviors.laser_guidance import LaserGuidanceSettings
from lsm.area import OperatingArea

# Bounds of what a mission may ask of a multicopter; each Field names the one it uses.
MAX_ALTITUDE = 10_000.0
"""m above home: multicopters lose lift in thin air; their service ceilings are a few
kilometres and the highest flights reached about 10 km, so no mission flies higher."""
MAX_RANGE = 50_000.0
"""m horizontally from home: a multicopter's battery lasts under an hour at up to about
20 m/s, i.e. some 35 km out and back at best; 50 km bounds every mission."""
MAX_WAIT = 3_600.0
"""s: the longest wait or timeout of a behaviour; an hour is more than a multicopter's
battery can hover."""
MAX_TRIES = 100
"""Retries of a search or a landing: each costs a flight of tens of seconds and a share of
the battery, so a hundred is more than any battery allows."""
MAX_WAYPOINTS = 1_000
"""Waypoints of a mission: more legs than a multicopter's endurance flies (1000 legs of 50 m
are 50 km), about the size of the autopilots' own mission stores (ArduPilot keeps some 700
items on most boards); each one is a behaviour of the tree."""

Altitude = Annotated[float, Field(gt=0, le=MAX_ALTITUDE)]
"""m above home, (0, MAX_ALTITUDE]."""
Horizontal = Annotated[float, Field(ge=-MAX_RANGE, le=MAX_RANGE)]
"""ENU x or y, m from home, within MAX_RANGE."""


class ApproachSettings(BaseModel):
    """How the vehicle reaches the chosen site: the thesis's climb to the clear altitude,
    traverse and descent (eq. 3.4-3.5), or a minimum-snap trajectory planned over the
    terrain the vehicle has mapped (Mittal et al. III-D), with the thesis's as fallback."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    method: Literal["clear_altitude", "trajectory"] = Field(
        "clear_altitude", description="clear_altitude: climb, traverse, descend (thesis); "
        "trajectory: a minimum-snap trajectory around what stands above the flight altitude "
        "(needs a mapping detector: detector elevation; else the thesis's approach is flown)"
    )
    vehicle_radius: float = Field(
        1.5, gt=0, le=100, description="m: the vehicle's radius plus a lateral margin; "
        "every mapped obstacle within it counts, up to 100 m"
    )
    vertical_margin: float | None = Field(
        None, ge=0, le=MAX_ALTITUDE, description="m kept between the vehicle and the top of "
        "every mapped obstacle on the way (raised by k_sigma standard deviations of the map), "
        "up to 10 km; unset: landing.clear_altitude_buffer, the thesis's z_buffer, so the "
        "trajectory keeps the clear altitude's margin over the ground it has mapped"
    )
    k_sigma: float = Field(
        2.0, ge=0, le=10, description="standard deviations of a cell's height uncertainty "
        "added to its top, 0 to 10"
    )
    min_height: float = Field(
        10.0, gt=0, le=MAX_ALTITUDE, description="m above the site where the trajectory ends "
        "at least (higher when an obstacle within vehicle_radius of the site needs it for "
        "vertical_margin; descending on the way from higher up, climbing first from lower "
        "down; the vehicle then descends vertically), up to 10 km"
    )
    max_speed: float = Field(
        5.0, gt=0, le=50, description="m/s peak speed of the trajectory, up to 50 m/s"
    )
    max_acceleration: float = Field(
        2.0, gt=0, le=20, description="m/s^2 peak acceleration of the trajectory, up to 20"
    )
    max_climb_speed: float = Field(
        2.5, gt=0, le=20, description="m/s peak climb rate of the trajectory (ArduPilot's "
        "WPNAV_SPEED_UP), up to 20"
    )
    max_descent_speed: float = Field(
        1.5, gt=0, le=20, description="m/s peak descent rate of the trajectory (ArduPilot's "
        "WPNAV_SPEED_DN), up to 20"
    )
    max_tracking_error: float = Field(
        5.0, gt=0, le=1000, description="m the vehicle may stray from the trajectory before "
        "the approach falls back to the thesis's, up to 1 km"
    )


class DescentWatchSettings(BaseModel):
    """The optical-flow watch of the blind descent to the verification altitude (Lee et al.
    2019, sections 3.3 and 4.2): when the descent camera's flow flags an obstacle, the
    vehicle stops descending, steps away from it and resumes; during the landing that
    follows, it climbs back instead and the try fails; the flow thresholds are
    ``perception.descent_flow``'s."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    enabled: bool = Field(
        False, description="watch the descent (renders a greyscale camera during it); off: "
        "the thesis's blind descent"
    )
    step: float = Field(
        1.5, gt=0, le=100, description="m moved sideways away from a flagged obstacle per "
        "sighting, up to 100 m"
    )
    max_offset: float = Field(
        3.0, ge=0, le=1000, description="m the descent column may move from the site's, in "
        "all, up to 1 km; with no room left to step away the vehicle climbs back to where "
        "the descent began and the try fails (the site is tried again or another chosen)"
    )
    settle: float = Field(
        1.0, ge=0, le=MAX_WAIT, description="s after resuming the descent before the flow "
        "counts again (the vehicle's sideways motion dies down), up to an hour"
    )
    land: bool = Field(
        True, description="watch the landing from the verification altitude too: a flagged "
        "obstacle, or something entering the column below (the rangefinder), aborts the "
        "landing with a climb back to the verification altitude and the try fails"
    )
    ban_after: int = Field(
        1, ge=0, le=100, description="retreats (the landing aborted, or no room left to step "
        "away) from one site before it is banned like a site that fails verification, 0 .. "
        "100 (0: never; 2 gives a site a passing car crossed another try)"
    )
    column_margin: float = Field(
        0.5, gt=0, le=100, description="m the rangefinder may read the ground higher than "
        "the lowest it read during the landing (or the site) before something counts as "
        "in the column, up to 100 m"
    )


class LandingSettings(BaseModel):
    """How the landing phase flies: altitudes, durations, search pattern, retries, battery."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    verification_altitude: float = Field(
        2.5, gt=0, le=MAX_ALTITUDE, description="m above the site to hover at for "
        "verification, up to 10 km (a multicopter's ceiling)"
    )
    verify: bool = Field(
        True, description="re-detect the chosen site from the verification altitude before "
        "landing (thesis 3.3.1); false lands after the blind descent, for comparisons"
    )
    verify_fresh: bool = Field(
        False, description="count only a re-detection made during this hover: a site seen "
        "low earlier (e.g. on takeoff) may since have been walked or driven onto (worlds "
        "with moving obstacles); false: any earlier low look verifies at once"
    )
    verification_duration: float = Field(
        10.0, gt=0, le=MAX_WAIT, description="s of clock time to wait for the site's "
        "re-detection, up to an hour (more than a battery hovers)"
    )
    clear_altitude_buffer: float = Field(
        10.0, ge=0, le=MAX_ALTITUDE, description="z_buffer of thesis eq. 3.4: margin above "
        "the obstacle altitude, m, up to 10 km (a multicopter's ceiling)"
    )
    failsafe_altitude: float = Field(
        120.0, gt=0, le=MAX_ALTITUDE, description="z_failsafe of thesis eq. 3.5: cap of the "
        "clear altitude, m above home, up to 10 km (a multicopter's ceiling)"
    )
    acceptance_radius: float = Field(
        1.0, gt=0, le=1000, description="a waypoint is reached within this distance (m, "
        "horizontal and vertical), up to 1 km"
    )
    centring_radius: float = Field(
        0.5, gt=0, le=1000, description="after verification the vehicle centres over the "
        "verified site to within this distance (m, up to 1 km) before landing"
    )
    search_rectangle: tuple[
        Annotated[float, Field(gt=0, le=2 * MAX_RANGE)],
        Annotated[float, Field(gt=0, le=2 * MAX_RANGE)],
    ] = Field(
        (60.0, 40.0), description="width (east) x height (north) of the search pattern, m; "
        "each > 0 and at most 100 km (twice the 50 km a multicopter flies from home)"
    )
    pattern_center_radius: float = Field(
        50.0, ge=0, le=MAX_RANGE, description="new pattern centres are drawn within this "
        "radius (m) of the last mission waypoint; at most 50 km (a multicopter's range)"
    )
    pattern_retries: int = Field(
        3, ge=1, le=MAX_TRIES, description="Retry(M): attempts of GetNextPatternCenterWP + "
        "LandingSiteSearch, 1..100 (each is a flight; no battery allows more)"
    )
    landing_retries: int = Field(
        10, ge=1, le=MAX_TRIES, description="Retry(N): attempts of the landing phase (sites "
        "tried), 1..100 (each is a flight; no battery allows more); each new try also needs "
        "the battery to allow it (landing_try_battery)"
    )
    landing_try_battery: float = Field(
        5.0, ge=0, le=100, description="% of battery a landing try is expected to cost at "
        "least: after a failed try another starts only if the battery, less the larger of "
        "this and the largest drop of a try so far, stays at or above battery_critical"
    )
    battery_reserve: float = Field(
        30.0, ge=0, le=100, description="% at or below which the remaining waypoints are skipped"
    )
    battery_critical: float = Field(
        15.0, ge=0, le=100, description="% at or below which the vehicle lands where it is"
    )
    command_timeout: float = Field(
        5.0, gt=0, le=MAX_WAIT, description="s of clock time for a command to be answered, "
        "up to an hour"
    )
    navigation_timeout: float = Field(
        300.0, gt=0, le=MAX_WAIT, description="s of clock time for one navigation "
        "(waypoint, pattern, takeoff, landing), up to an hour (more than a battery flies)"
    )
    preflight_timeout: float = Field(
        120.0, gt=0, le=MAX_WAIT, description="s of clock time to wait for link, GPS fix "
        "and prearm checks, up to an hour"
    )
    gps_loss_timeout: float = Field(
        5.0, gt=0, le=MAX_WAIT, description="s without a 3D GPS fix in flight after which "
        "the vehicle lands where it is, up to an hour"
    )
    approach: ApproachSettings = Field(
        default_factory=ApproachSettings, description="how the vehicle reaches the site"
    )
    laser_guidance: LaserGuidanceSettings = Field(
        default_factory=LaserGuidanceSettings, description="after a GPS loss: follow a ground "
        "laser to land (docs/gps-denied.md)"
    )
    descent_watch: DescentWatchSettings = Field(
        default_factory=DescentWatchSettings, description="optical-flow obstacle watch of "
        "the descent to the verification altitude"
    )

    @model_validator(mode="after")
    def _check(self) -> LandingSettings:
        if self.battery_critical > self.battery_reserve:
            raise ValueError(
                f"battery_critical ({self.battery_critical} %) must not exceed battery_reserve "
                f"({self.battery_reserve} %)"
            )
        return self


Waypoint = tuple[Horizontal, Horizontal, Altitude]


class MissionPlan(BaseModel):
    """The mission: waypoints flown at altitude, then the landing phase.

    ``waypoints`` are ENU metres (z = altitude above home), flown in order after takeoff.
    The search patterns of the landing phase are flown at ``cruise_altitude``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    waypoints: list[Waypoint] = Field(
        ..., min_length=1, max_length=MAX_WAYPOINTS, description="ENU waypoints (x east, "
        "y north, z above home), m: 1 to 1000 of them, each within 50 km of home (a "
        "battery's range) and 0 < z <= 10 km (a multicopter's ceiling)"
    )
    takeoff_altitude: float | None = Field(
        None, gt=0, le=MAX_ALTITUDE, description="m above home, up to 10 km (a "
        "multicopter's ceiling); default: the first waypoint's z"
    )
    cruise_altitude: float = Field(
        100.0, gt=0, le=MAX_ALTITUDE, description="m above home at which search patterns "
        "are flown, up to 10 km (a multicopter's ceiling)"
    )
    landing: LandingSettings = Field(default_factory=LandingSettings)
    geofence: InstanceOf[OperatingArea] | None = Field(
        None, description="the operating area (ENU) sites, search patterns and the approach "
        "stay in; None: anywhere"
    )
    geofence_upload: bool = Field(
        False, description="Preflight uploads ``geofence`` to the autopilot as its own "
        "geofence and enables it"
    )

    @model_validator(mode="after")
    def _check(self) -> MissionPlan:
        for i, (x, y, _) in enumerate(self.waypoints):
            if math.hypot(x, y) > MAX_RANGE:
                raise ValueError(f"waypoints[{i}]: {math.hypot(x, y):.0f} m from home, more "
                                 f"than the {MAX_RANGE:.0f} m a multicopter flies")
        return self

    @property
    def effective_takeoff_altitude(self) -> float:
        """Takeoff altitude in m above home: the explicit one or the first waypoint's z."""
        if self.takeoff_altitude is not None:
            return self.takeoff_altitude
        return self.waypoints[0][2]
