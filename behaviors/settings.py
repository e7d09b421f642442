"""Validated settings of the landing behaviours and the mission plan (pydantic v2).

Positions are local ENU metres (origin at home, z up, z = altitude above home); durations are
seconds of the injected clock; battery levels are percent. Nothing here is an angle, so YAML
needs no degree conversion for these models.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator


class LandingSettings(BaseModel):
    """How the landing phase flies: altitudes, durations, search pattern, retries, battery."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    verification_altitude: float = Field(
        2.5, gt=0, description="m above the site to hover at for verification"
    )
    verify: bool = Field(
        True, description="re-detect the chosen site from the verification altitude before "
        "landing (thesis 3.3.1); false lands after the blind descent, for comparisons"
    )
    verification_duration: float = Field(
        10.0, gt=0, description="s of clock time to wait for the site's re-detection"
    )
    clear_altitude_buffer: float = Field(
        10.0, ge=0, description="z_buffer of thesis eq. 3.4: margin above the obstacle altitude, m"
    )
    failsafe_altitude: float = Field(
        120.0, gt=0, description="z_failsafe of thesis eq. 3.5: cap of the clear altitude, m"
    )
    acceptance_radius: float = Field(
        1.0, gt=0, description="a waypoint is reached within this distance (m, horizontal and "
        "vertical)"
    )
    centring_radius: float = Field(
        0.5, gt=0, description="after verification the vehicle centres over the verified "
        "site to within this distance (m) before landing"
    )
    search_rectangle: tuple[float, float] = Field(
        (60.0, 40.0), description="width (east) x height (north) of the search pattern, m"
    )
    pattern_center_radius: float = Field(
        50.0, ge=0, description="new pattern centres are drawn within this radius (m) of the "
        "last mission waypoint"
    )
    pattern_retries: int = Field(
        3, ge=1, description="Retry(M): attempts of GetNextPatternCenterWP + LandingSiteSearch"
    )
    landing_retries: int = Field(
        10, ge=1, description="Retry(N): attempts of the landing phase (sites tried); each "
        "new try also needs the battery to allow it (landing_try_battery)"
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
        5.0, gt=0, description="s of clock time for a command to be answered"
    )
    navigation_timeout: float = Field(
        300.0, gt=0, description="s of clock time for one navigation (waypoint, pattern, "
        "takeoff, landing)"
    )
    preflight_timeout: float = Field(
        120.0, gt=0, description="s of clock time to wait for link, GPS fix and prearm checks"
    )
    gps_loss_timeout: float = Field(
        5.0, gt=0, description="s without a 3D GPS fix in flight after which the vehicle "
        "lands where it is"
    )

    @model_validator(mode="after")
    def _check(self) -> LandingSettings:
        width, height = self.search_rectangle
        if not (width > 0 and height > 0):
            raise ValueError(
                f"search_rectangle: width and height must be > 0 m, got {self.search_rectangle}"
            )
        if self.battery_critical > self.battery_reserve:
            raise ValueError(
                f"battery_critical ({self.battery_critical} %) must not exceed battery_reserve "
                f"({self.battery_reserve} %)"
            )
        return self


Waypoint = tuple[float, float, float]


class MissionPlan(BaseModel):
    """The mission: waypoints flown at altitude, then the landing phase.

    ``waypoints`` are ENU metres (z = altitude above home), flown in order after takeoff.
    The search patterns of the landing phase are flown at ``cruise_altitude``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    waypoints: list[Waypoint] = Field(
        ..., min_length=1, description="ENU waypoints (x east, y north, z above home), m"
    )
    takeoff_altitude: float | None = Field(
        None, gt=0, description="m above home; default: the first waypoint's z"
    )
    cruise_altitude: float = Field(
        100.0, gt=0, description="m above home at which search patterns are flown"
    )
    landing: LandingSettings = Field(default_factory=LandingSettings)

    @model_validator(mode="after")
    def _check(self) -> MissionPlan:
        for i, (_, _, z) in enumerate(self.waypoints):
            if z <= 0:
                raise ValueError(f"waypoints[{i}]: altitude must be > 0 m above home, got {z}")
        return self

    @property
    def effective_takeoff_altitude(self) -> float:
        """Takeoff altitude in m above home: the explicit one or the first waypoint's z."""
        if self.takeoff_altitude is not None:
            return self.takeoff_altitude
        return self.waypoints[0][2]
