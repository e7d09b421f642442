"""Validated settings of the embedded multicopter simulator (pydantic v2).

Defaults follow ArduPilot Copter's stock parameters where one exists (WPNAV_SPEED, WPNAV_ACCEL,
LAND_SPEED, DISARM_DELAY, ...), so a flight against the SITL looks like one against the real
autopilot's SITL.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator


class HomeSettings(BaseModel):
    """Geodetic position of home (the origin of the local ENU frame, on the ground)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    lat: float = Field(47.397742, ge=-90, le=90, description="latitude, degrees")
    lon: float = Field(8.545594, ge=-180, le=180, description="longitude, degrees")
    alt: float = Field(488.0, ge=-500, le=9000, description="ground altitude AMSL, metres")


class WindSettings(BaseModel):
    """Constant wind plus seeded gusts (first-order Gauss-Markov per horizontal axis)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    speed: float = Field(0.0, ge=0, le=30, description="constant wind speed, m/s")
    direction: float = Field(
        0.0, ge=0, lt=360, description="direction the wind blows FROM, degrees clockwise from north"
    )
    gust_sigma: float = Field(0.0, ge=0, le=15, description="1-sigma gust speed per axis, m/s")
    gust_time_constant: float = Field(
        3.0, gt=0, description="correlation time of the gusts, seconds"
    )


class BatterySettings(BaseModel):
    """A LiPo pack: capacity and a current draw that grows with climb rate and speed."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    capacity_mah: float = Field(5000.0, gt=0, description="usable capacity, mAh")
    cells: int = Field(4, ge=1, le=14, description="series cell count")
    idle_current: float = Field(0.5, ge=0, description="draw when disarmed, A")
    hover_current: float = Field(18.0, ge=0, description="draw in hover, A")
    climb_current: float = Field(4.0, ge=0, description="extra draw per m/s of climb, A")
    speed_current: float = Field(0.3, ge=0, description="extra draw per m/s of ground speed, A")


class MessageRates(BaseModel):
    """Telemetry the PX4 personality streams by itself, Hz (0 = off).

    ArduPilot streams nothing but HEARTBEAT until asked (SET_MESSAGE_INTERVAL); these are
    its rates only when a client asks for the message's default rate (interval 0).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    heartbeat: float = Field(1.0, ge=0)
    attitude: float = Field(20.0, ge=0)
    global_position_int: float = Field(10.0, ge=0)
    local_position_ned: float = Field(10.0, ge=0)
    distance_sensor: float = Field(10.0, ge=0)
    sys_status: float = Field(2.0, ge=0)
    extended_sys_state: float = Field(2.0, ge=0)
    battery_status: float = Field(1.0, ge=0)
    home_position: float = Field(0.5, ge=0)
    gps_raw_int: float = Field(2.0, ge=0)
    system_time: float = Field(1.0, ge=0)
    mission_current: float = Field(1.0, ge=0)
    ekf_status_report: float = Field(0.0, ge=0, description="ArduPilot only, when asked")


class SitlSettings(BaseModel):
    """Everything the embedded SITL can be told: the airframe, the world and the link."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    home: HomeSettings = HomeSettings()
    wind: WindSettings = WindSettings()
    battery: BatterySettings = BatterySettings()
    rates: MessageRates = MessageRates()

    # Airframe limits (ArduPilot WPNAV_SPEED 10 m/s, WPNAV_SPEED_UP 2.5, WPNAV_SPEED_DN 1.5,
    # WPNAV_ACCEL 2.5 m/s^2, PILOT_ACCEL_Z 2.5 m/s^2).
    max_horizontal_speed: float = Field(10.0, gt=0, description="m/s")
    max_climb_speed: float = Field(2.5, gt=0, description="m/s")
    max_descent_speed: float = Field(1.5, gt=0, description="m/s")
    max_horizontal_acceleration: float = Field(2.5, gt=0, description="m/s^2")
    max_vertical_acceleration: float = Field(2.5, gt=0, description="m/s^2")
    max_yaw_rate: float = Field(90.0, gt=0, description="deg/s")
    drag: float = Field(0.25, ge=0, description="air drag coefficient pulling toward wind, 1/s")
    physics_step: float = Field(0.05, gt=0, le=0.1, description="largest integration step, s")

    # Landing (ArduPilot LAND_SPEED 0.5 m/s below LAND_ALT_LOW 10 m; PX4 MPC_LAND_SPEED 0.7).
    land_speed: float = Field(0.5, gt=0, description="final descent speed in LAND, m/s")
    land_speed_high: float = Field(
        0.0, ge=0, description="descent speed above land_alt_low in LAND, m/s (0 = max descent)"
    )
    land_alt_low: float = Field(10.0, ge=0, description="AGL below which LAND slows down, m")
    px4_land_speed: float = Field(0.7, gt=0, description="PX4 final descent speed, m/s")
    rtl_altitude: float = Field(15.0, ge=0, description="RTL climbs to this above home, m")
    waypoint_radius: float = Field(
        2.0, gt=0, le=1000, description="a mission waypoint counts as reached this close, m "
        "(ArduPilot WPNAV_RADIUS, PX4 NAV_ACC_RAD)"
    )
    mission_capacity: int = Field(
        1000, ge=2, le=65535, description="the most items a mission, fence or rally plan holds"
    )
    px4_takeoff_altitude: float = Field(2.5, gt=0, description="PX4 default takeoff height, m")

    # Safety and refusals.
    arming_settle_time: float = Field(
        5.0, ge=0, description="sim seconds after boot before the EKF/GPS let the vehicle arm"
    )
    position_settle_time: float | None = Field(
        None, ge=0, description="sim seconds after boot before the EKF has an absolute position "
        "(home set; GUIDED, AUTO, LOITER, RTL allowed and armable); None: with "
        "arming_settle_time. ArduPilot judges its prearm checks for the current mode, so "
        "between the two it arms in STABILIZE but refuses GUIDED ('Arm: Need Position "
        "Estimate')"
    )
    disarm_delay: float = Field(
        10.0, ge=0, description="armed on the ground this long (no takeoff) -> disarm, s"
    )
    land_disarm_delay: float = Field(1.0, ge=0, description="ArduPilot LAND touchdown -> disarm, s")
    px4_land_disarm_delay: float = Field(2.0, ge=0, description="PX4 touchdown -> disarm, s")
    guided_velocity_timeout: float = Field(
        3.0, gt=0, description="ArduPilot stops a velocity target not refreshed this long, s"
    )
    offboard_loss_timeout: float = Field(
        1.0, gt=0, description="PX4 leaves OFFBOARD when setpoints stop this long, s"
    )
    offboard_min_rate: float = Field(
        2.0, gt=0, description="PX4 needs setpoints at least this often (Hz) to enter OFFBOARD"
    )
    crash_speed: float = Field(
        2.0, gt=0, description="touching down faster than this (vertical, m/s) is a crash"
    )
    crash_horizontal_speed: float = Field(
        2.0, gt=0, description="touching the ground moving faster than this sideways (m/s) "
        "is a crash (flying into rising terrain)"
    )
    crash_slope: float = Field(
        20.0, gt=0, lt=90, description="touching down on a slope steeper than this (deg) tips over"
    )
    slope_baseline: float = Field(
        0.5, gt=0, description="half-distance of the finite differences for the slope, m"
    )

    # Sensors.
    rangefinder_min: float = Field(0.2, ge=0, description="m")
    rangefinder_max: float = Field(40.0, gt=0, description="m")

    # Link.
    system_id: int = Field(1, ge=1, le=255)
    component_id: int = Field(1, ge=1, le=255)
    unix_time_at_boot: float = Field(
        1.7e9, ge=0, description="SYSTEM_TIME epoch of boot, Unix seconds (deterministic)"
    )

    @model_validator(mode="after")
    def _ranges_make_sense(self) -> SitlSettings:
        if self.rangefinder_min >= self.rangefinder_max:
            raise ValueError("rangefinder_min: must be below rangefinder_max")
        if (self.position_settle_time is not None
                and self.position_settle_time < self.arming_settle_time):
            raise ValueError("position_settle_time: must not be before arming_settle_time")
        return self
