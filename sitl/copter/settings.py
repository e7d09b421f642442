"""Validated settings of the embedded multicopter simulator (pydantic v2).

Defaults follow ArduPilot Copter's stock parameters where one exists (WPNAV_SPEED, WPNAV_ACCEL,
LAND_SPEED, DISARM_DELAY, ...), so a flight against the SITL looks like one against the real
autopilot's SITL.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator

from sitl.sensors.laser import LaserSettings


class HomeSettings(BaseModel):
    """Geodetic position of home (the origin of the local ENU frame, on the ground)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    lat: float = Field(
        47.397742, ge=-89, le=89, description="latitude, degrees, -89..89: east and north "
        "about home are undefined at a pole, and a mission 50 km from home must not cross one"
    )
    lon: float = Field(8.545594, ge=-180, le=180, description="longitude, degrees")
    alt: float = Field(488.0, ge=-500, le=9000, description="ground altitude AMSL, metres")


class HomeChangeSettings(BaseModel):
    """A ground station moving home in flight: at ``at`` s after boot it sends
    MAV_CMD_DO_SET_HOME with the ground at (``east``, ``north``) m from where the vehicle
    booted, as an operator clicking "set home here" on a map does."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    at: float = Field(..., ge=0, le=86_400, description="sim seconds after boot, up to a day")
    east: float = Field(..., ge=-50_000, le=50_000, description="m east of the boot home, "
                        "within 50 km (ArduPilot sets no home farther from its EKF origin)")
    north: float = Field(..., ge=-50_000, le=50_000, description="m north of the boot home, "
                         "within 50 km")


class WindSettings(BaseModel):
    """Constant wind plus seeded gusts (first-order Gauss-Markov per horizontal axis)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    speed: float = Field(0.0, ge=0, le=30, description="constant wind speed, m/s")
    direction: float = Field(
        0.0, ge=0, lt=360, description="direction the wind blows FROM, degrees clockwise from north"
    )
    gust_sigma: float = Field(0.0, ge=0, le=15, description="1-sigma gust speed per axis, m/s")
    gust_time_constant: float = Field(
        3.0, gt=0, le=3600, description="correlation time of the gusts, seconds, up to an hour"
    )


class BatterySettings(BaseModel):
    """A LiPo pack: capacity and a current draw that grows with climb rate and speed."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    capacity_mah: float = Field(
        5000.0, gt=0, le=1_000_000, description="usable capacity, mAh, up to 1000 Ah (the "
        "largest multicopter packs hold tens of Ah)"
    )
    cells: int = Field(4, ge=1, le=14, description="series cell count")
    idle_current: float = Field(
        0.5, ge=0, le=1000, description="draw when disarmed, A, up to 1000"
    )
    hover_current: float = Field(
        18.0, ge=0, le=1000, description="draw in hover, A, up to 1000 (heavy-lift octocopters "
        "draw a few hundred)"
    )
    climb_current: float = Field(
        4.0, ge=0, le=1000, description="extra draw per m/s of climb, A, up to 1000"
    )
    speed_current: float = Field(
        0.3, ge=0, le=1000, description="extra draw per m/s of ground speed, A, up to 1000"
    )


class GpsLossSettings(BaseModel):
    """A scheduled loss of GPS (jamming, an urban canyon) and how the estimator copes.

    From ``at`` on, GPS_RAW_INT reports no fix and the EKF dead-reckons: the position it
    reports (and flies position targets by) drifts from the truth by a velocity error, a
    constant bias plus a scale error of the speed flown plus a random walk, all seeded.
    With ``velocity_aiding`` (an optical-flow sensor: ArduPilot EK3_SRC1_VELXY, PX4
    EKF2_OF_CTRL) the EKF keeps a relative position, so GUIDED/OFFBOARD and velocity targets
    still work. Without it the position is lost ``failsafe_delay`` s later and the autopilot
    does what its documentation says: ArduPilot's EKF failsafe (FS_EKF_ACTION 1) switches a
    mode that needs a position to LAND, PX4's position-loss failsafe (COM_POS_FS_DELAY) to
    AUTO.LAND; both refuse the position modes from then on.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    at: float = Field(
        ..., ge=0, le=86_400, description="sim seconds after boot when GPS is lost, up to a day"
    )
    duration: float | None = Field(
        None, gt=0, le=86_400, description="s until the fix returns (None: lost for good)"
    )
    velocity_aiding: bool = Field(
        True, description="an optical-flow sensor keeps the velocity (and a relative position)"
    )
    drift_bias: float = Field(
        0.05, ge=0, le=10, description="1-sigma per axis of the dead-reckoning velocity bias, m/s"
    )
    drift_scale: float = Field(
        0.03, ge=0, le=1, description="1-sigma scale error of the speed flown (0.03 = 3 %)"
    )
    drift_walk: float = Field(
        0.02, ge=0, le=10, description="random walk of the velocity error, m/s per sqrt(s)"
    )
    failsafe_delay: float = Field(
        1.0, ge=0, le=60, description="s of bad position before the failsafe without "
        "velocity aiding (ArduPilot's EKF check: 1 s; PX4 COM_POS_FS_DELAY: 1 s)"
    )


MAX_STREAM_RATE = 100.0
"""Hz: the fastest stream; autopilots stream at up to 50 Hz (ArduPilot's SRn_ rates), and a
telemetry radio carries a few hundred small messages a second in all."""
_RATE = "Hz, 0 (off) .. 100"


class MessageRates(BaseModel):
    """Telemetry the PX4 personality streams by itself, Hz (0 = off).

    ArduPilot streams nothing but HEARTBEAT until asked (SET_MESSAGE_INTERVAL); these are
    its rates only when a client asks for the message's default rate (interval 0).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    heartbeat: float = Field(1.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    attitude: float = Field(20.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    global_position_int: float = Field(10.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    local_position_ned: float = Field(10.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    distance_sensor: float = Field(10.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    sys_status: float = Field(2.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    extended_sys_state: float = Field(2.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    battery_status: float = Field(1.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    home_position: float = Field(0.5, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    gps_raw_int: float = Field(2.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    system_time: float = Field(1.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    mission_current: float = Field(1.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    vfr_hud: float = Field(4.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    ekf_status_report: float = Field(
        0.0, ge=0, le=MAX_STREAM_RATE, description="ArduPilot only, when asked; " + _RATE
    )
    attitude_quaternion: float = Field(10.0, ge=0, le=MAX_STREAM_RATE, description=_RATE)
    altitude: float = Field(1.0, ge=0, le=MAX_STREAM_RATE, description="PX4 only; " + _RATE)
    fence_status: float = Field(
        0.0, ge=0, le=MAX_STREAM_RATE,
        description="ArduPilot only, when asked and a fence is enabled; " + _RATE,
    )


class SitlSettings(BaseModel):
    """Everything the embedded SITL can be told: the airframe, the world and the link."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    home: HomeSettings = HomeSettings()
    wind: WindSettings = WindSettings()
    battery: BatterySettings = BatterySettings()
    rates: MessageRates = MessageRates()

    # Airframe limits (ArduPilot WPNAV_SPEED 10 m/s, WPNAV_SPEED_UP 2.5, WPNAV_SPEED_DN 1.5,
    # WPNAV_ACCEL 2.5 m/s^2, PILOT_ACCEL_Z 2.5 m/s^2).
    max_horizontal_speed: float = Field(
        10.0, gt=0, le=50, description="m/s, up to 50 (ArduPilot's WPNAV_SPEED tops out at "
        "20 m/s; racing multicopters reach about 50)"
    )
    max_climb_speed: float = Field(2.5, gt=0, le=20, description="m/s, up to 20")
    max_descent_speed: float = Field(1.5, gt=0, le=20, description="m/s, up to 20")
    max_horizontal_acceleration: float = Field(
        2.5, gt=0, le=50, description="m/s^2, up to 50 (5 g)"
    )
    max_vertical_acceleration: float = Field(
        2.5, gt=0, le=50, description="m/s^2, up to 50 (5 g)"
    )
    max_yaw_rate: float = Field(
        90.0, gt=0, le=1080, description="deg/s, up to 1080 (ArduPilot's ATC_RATE_Y_MAX limit)"
    )
    drag: float = Field(
        0.25, ge=0, le=100, description="air drag coefficient pulling toward wind, 1/s"
    )
    physics_step: float = Field(
        0.05, ge=0.001, le=0.1, description="largest integration step, s: 1 ms (a 1 kHz "
        "loop, faster than any autopilot's) .. 0.1 s"
    )

    # Landing (ArduPilot LAND_SPEED 0.5 m/s below LAND_ALT_LOW 10 m; PX4 MPC_LAND_SPEED 0.7).
    land_speed: float = Field(
        0.5, gt=0, le=20, description="final descent speed in LAND, m/s, up to 20"
    )
    land_speed_high: float = Field(
        0.0, ge=0, le=20, description="descent speed above land_alt_low in LAND, m/s, up to 20 "
        "(0 = max descent)"
    )
    land_alt_low: float = Field(
        10.0, ge=0, le=327, description="AGL below which LAND slows down, m, up to 327 "
        "(ArduPilot's LAND_ALT_LOW is an int16 of cm)"
    )
    px4_land_speed: float = Field(
        0.7, gt=0, le=20, description="PX4 final descent speed, m/s, up to 20"
    )
    rtl_altitude: float = Field(
        15.0, ge=0, le=10_000, description="RTL climbs to this above home, m, up to 10 km (a "
        "multicopter's ceiling)"
    )
    waypoint_radius: float = Field(
        2.0, gt=0, le=1000, description="a mission waypoint counts as reached this close, m "
        "(ArduPilot WPNAV_RADIUS, PX4 NAV_ACC_RAD)"
    )
    mission_capacity: int = Field(
        1000, ge=2, le=65535, description="the most items a mission, fence or rally plan holds"
    )
    px4_takeoff_altitude: float = Field(
        2.5, gt=0, le=10_000, description="PX4 default takeoff height, m, up to 10 km"
    )

    # Safety and refusals.
    arming_settle_time: float = Field(
        5.0, ge=0, le=3600, description="sim seconds after boot before the EKF/GPS let the "
        "vehicle arm, up to an hour"
    )
    position_settle_time: float | None = Field(
        None, ge=0, le=3600, description="sim seconds (up to an hour) after boot before the "
        "EKF has an absolute position (home set; GUIDED, AUTO, LOITER, RTL allowed and "
        "armable); None: with "
        "arming_settle_time. ArduPilot judges its prearm checks for the current mode, so "
        "between the two it arms in STABILIZE but refuses GUIDED ('Arm: Need Position "
        "Estimate')"
    )
    disarm_delay: float = Field(
        10.0, ge=0, le=127, description="armed on the ground this long (no takeoff) -> "
        "disarm, s, up to 127 (ArduPilot's DISARM_DELAY is an int8)"
    )
    land_disarm_delay: float = Field(
        1.0, ge=0, le=60, description="ArduPilot LAND touchdown -> disarm, s, up to a minute"
    )
    px4_land_disarm_delay: float = Field(
        2.0, ge=0, le=60, description="PX4 touchdown -> disarm, s, up to a minute"
    )
    guided_velocity_timeout: float = Field(
        3.0, gt=0, le=3600, description="ArduPilot stops a velocity target not refreshed this "
        "long, s, up to an hour"
    )
    offboard_loss_timeout: float = Field(
        1.0, gt=0, le=60, description="PX4 leaves OFFBOARD when setpoints stop this long, s, "
        "up to a minute"
    )
    crash_speed: float = Field(
        2.0, gt=0, le=100, description="touching down faster than this (vertical, m/s, up to "
        "100) is a crash"
    )
    crash_horizontal_speed: float = Field(
        2.0, gt=0, le=100, description="touching the ground moving faster than this sideways "
        "(m/s, up to 100) is a crash (flying into rising terrain)"
    )
    crash_slope: float = Field(
        20.0, gt=0, lt=90, description="touching down on a slope steeper than this (deg) tips over"
    )
    slope_baseline: float = Field(
        0.5, gt=0, le=100, description="half-distance of the finite differences for the "
        "slope, m, up to 100"
    )

    # Sensors.
    rangefinder_min: float = Field(
        0.2, ge=0, le=327, description="m, up to 327 (RNGFND1_MIN_CM is an int16 of cm)"
    )
    rangefinder_max: float = Field(
        40.0, gt=0, le=327, description="m, up to 327 (RNGFND1_MAX_CM is an int16 of cm)"
    )

    # GPS-denied flight (docs/gps-denied.md): both None in an ordinary flight.
    gps_loss: GpsLossSettings | None = Field(None, description="a scheduled loss of GPS")
    laser: LaserSettings | None = Field(
        None, description="a ground laser and the vehicle's ring of light sensors"
    )
    # A home moved in flight (docs/how-to/live-flights.md): None in an ordinary flight.
    home_change: HomeChangeSettings | None = Field(
        None, description="a ground station's DO_SET_HOME during the flight"
    )

    # Link.
    system_id: int = Field(1, ge=1, le=255, description="MAVLink system id, 1..255")
    component_id: int = Field(1, ge=1, le=255, description="MAVLink component id, 1..255")
    unix_time_at_boot: float = Field(
        1.7e9, ge=0, le=4.0e9, description="SYSTEM_TIME epoch of boot, Unix seconds "
        "(deterministic), up to 4e9 (the year 2096)"
    )

    @model_validator(mode="after")
    def _ranges_make_sense(self) -> SitlSettings:
        if self.rangefinder_min >= self.rangefinder_max:
            raise ValueError("rangefinder_min: must be below rangefinder_max")
        if (self.position_settle_time is not None
                and self.position_settle_time < self.arming_settle_time):
            raise ValueError("position_settle_time: must not be before arming_settle_time")
        return self
