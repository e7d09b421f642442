"""The simulated autopilot's flight logic, common to both personalities.

An :class:`Autopilot` owns the arming state, the flight mode and what the position controller
is asked to do; it answers commands with MAVLink ``MAV_RESULT`` codes and queues STATUSTEXT
lines, but knows nothing of bytes or links (that is :mod:`sitl.copter.server`). The
personalities in :mod:`sitl.copter.personalities` fill in the mode tables and the refusals.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .auto import AutoFlier
from .battery import Battery
from .fence import Fence
from .geo import GeoFrame
from .kinematics import Contact, Multicopter, Setpoint
from .mission import MissionStore
from .params import ParameterTable
from .settings import SitlSettings

ACCEPTED = mavlink.MAV_RESULT_ACCEPTED
DENIED = mavlink.MAV_RESULT_DENIED
FAILED = mavlink.MAV_RESULT_FAILED
UNSUPPORTED = mavlink.MAV_RESULT_UNSUPPORTED
TEMPORARILY_REJECTED = mavlink.MAV_RESULT_TEMPORARILY_REJECTED

ON_GROUND = mavlink.MAV_LANDED_STATE_ON_GROUND
IN_AIR = mavlink.MAV_LANDED_STATE_IN_AIR
TAKEOFF = mavlink.MAV_LANDED_STATE_TAKEOFF
LANDING = mavlink.MAV_LANDED_STATE_LANDING

# How close (m) to a takeoff altitude counts as reached.
TAKEOFF_REACHED = 0.3
# Depth (m) below the vehicle of the target a landing descent aims at: the descent speed
# limit, not the target, sets the speed.
_FAR_BELOW = 1000.0
# Within this horizontal distance (m) of home, RTL starts its descent.
_RTL_RADIUS = 1.0
# Slowest speed (m/s) DO_CHANGE_SPEED sets (ArduPilot's WPNAV_WP_SPEED_MIN, 20 cm/s).
_MIN_SPEED = 0.2

Slope = Callable[[float, float], float]


@dataclass(frozen=True, slots=True)
class Touchdown:
    """Where and how fast the vehicle last touched the ground (ENU m, m/s)."""

    x: float
    y: float
    z: float
    speed: float
    vertical_speed: float
    slope_deg: float


class Autopilot:
    """Flight logic of a simulated multicopter autopilot.

    Args:
        settings: the SITL settings.
        model: the airframe it flies.
        battery: the pack it drains.
        slope: function (x, y) -> terrain slope in degrees at that point.
        ground_z: terrain height at home (ENU z of home on the ground, m).
    """

    #: personality name, e.g. "ardupilot"
    name = "base"
    #: MAV_AUTOPILOT value of the HEARTBEAT
    mav_autopilot = mavlink.MAV_AUTOPILOT_GENERIC
    #: mode name -> custom_mode
    modes: dict[str, int] = {}
    initial_mode = ""
    #: modes in which the vehicle holds a captured position (no RC on this vehicle)
    hold_modes: frozenset[str] = frozenset()
    #: modes in which the vehicle descends to land
    land_modes: frozenset[str] = frozenset()
    rtl_modes: frozenset[str] = frozenset()
    #: the mode that flies the stored mission
    auto_mode = ""
    #: ArduPilot keeps home as item 0 of the mission
    home_at_zero = False
    #: gives a downloaded item the float twin of the *_INT frame it was uploaded in
    #: (ArduPilot stores the altitude reference, not the frame)
    float_frames_on_download = False
    #: sends MISSION_CURRENT whenever the current item or the mission state changes (PX4);
    #: ArduPilot sends it only in its telemetry stream and when the current item is set
    announces_mission_current = False
    #: parameter rows (sitl.copter.params) and their float encoding
    param_table: tuple = ()
    param_bytewise = False
    #: the geofence it enforces (sitl.copter.fence)
    fence_class: type[Fence] = Fence

    def __init__(
        self,
        settings: SitlSettings,
        model: Multicopter,
        battery: Battery,
        slope: Slope,
        ground_z: float = 0.0,
        geo: GeoFrame | None = None,
    ) -> None:
        self.settings = settings
        self.model = model
        self.battery = battery
        self.slope = slope
        # The local frame's origin (the EKF origin, LOCAL_POSITION_NED's zero) stays where the
        # vehicle booted; home (RTL's destination, the reference of relative altitudes) starts
        # there and moves on arming and with MAV_CMD_DO_SET_HOME (set_home).
        self.origin_z = ground_z
        self.home_z = ground_z  # ENU z of home, m
        self.home_xy = (0.0, 0.0)  # ENU x, y of home in the EKF's frame, m
        home = settings.home
        self.home_geo = (home.lat, home.lon, home.alt)  # lat deg, lon deg, alt m AMSL
        # A ground station set home (DO_SET_HOME): arming no longer moves it.
        self.home_locked = False
        self.geo = geo or GeoFrame(home.lat, home.lon, home.alt, ground_z,
                                   lambda x, y: ground_z, self.name)
        self.mission = MissionStore(
            home_at_zero=self.home_at_zero, capacity=settings.mission_capacity
        )
        self.auto = AutoFlier(self)
        self.params = ParameterTable(
            self.param_table, bytewise=self.param_bytewise,
            settings=lambda: self.settings, apply=self.apply_settings,
        )
        # Set by DO_CHANGE_SPEED (m/s): the speeds guided and mission flight use, None for
        # the airframe's limits.
        self.speed_limit: float | None = None
        self.hold_yaw: float | None = None  # heading (rad) a reposition asked for
        self.climb_limit: float | None = None
        self.descent_limit: float | None = None
        self.time = 0.0
        self.armed = False
        self.mode = self.initial_mode
        self.flying = False  # a takeoff (or liftoff) happened since arming/landing
        self.took_off = False  # left the ground since the last arming
        self.crashed = False
        self.crash_reason = ""
        self.touchdown: Touchdown | None = None
        self.ground_since: float | None = None
        self.hold: tuple[float, float, float] = model.position
        self.guided = Setpoint(position=model.position, hold_ground=True)
        self.guided_velocity_time = -math.inf
        self.takeoff_target: float | None = None
        self.rtl_phase = ""
        self.rtl_altitude = 0.0
        self.texts: list[tuple[int, str]] = []
        self.home_changed = False
        # A scheduled GPS loss (sitl.copter.gps.GpsOutage), set by the simulator; None in an
        # ordinary flight.
        self.gps = None
        self.fence = self.fence_class(self)

    # ----------------------------------------------------------------- queries
    @property
    def settled(self) -> bool:
        """EKF and GPS have settled: arming checks pass (prearm-ok health bit)."""
        return self.time >= self.settings.arming_settle_time

    @property
    def position_known(self) -> bool:
        """The EKF has an absolute position: home is set, position modes may be entered."""
        s = self.settings
        settle = s.arming_settle_time if s.position_settle_time is None else s.position_settle_time
        if self.gps is not None and self.gps.position_failed(self.time):
            return False
        return self.time >= settle

    @property
    def gps_lost(self) -> bool:
        """GPS gives no fix now (a scheduled loss)."""
        return self.gps is not None and self.gps.lost

    def estimated_xy(self) -> tuple[float, float]:
        """The EKF's horizontal position (ENU m): the truth, plus the drift while GPS is lost."""
        m = self.model
        if self.gps is None or not self.gps.lost:
            return m.x, m.y
        dx, dy = self.gps.drift
        return m.x + dx, m.y + dy

    def estimate_to_truth(
        self, position: tuple[float, float, float]
    ) -> tuple[float, float, float]:
        """Where an absolute position target (in the EKF's frame) really is."""
        if self.gps is None or not self.gps.lost:
            return position
        dx, dy = self.gps.drift
        return position[0] - dx, position[1] - dy, position[2]

    def update_gps(self, dt: float) -> None:
        """Advance the GPS outage over a physics step; announce and act on changes."""
        gps = self.gps
        failed_before = gps.position_failed(self.time - dt)
        change = gps.advance(self.time, dt, (self.model.vx, self.model.vy))
        if change == "lost":
            self.on_gps_lost()
        elif change == "regained":
            self.text(mavlink.MAV_SEVERITY_INFO, "GPS 1: fix regained")
        elif gps.position_failed(self.time) and not failed_before:
            self.on_position_failed()

    def on_gps_lost(self) -> None:
        """GPS just dropped its fix (the personalities word it)."""
        self.text(mavlink.MAV_SEVERITY_INFO, "GPS 1: fix lost")

    def on_position_failed(self) -> None:
        """No horizontal position any more: the personality's failsafe."""

    @property
    def custom_mode(self) -> int:
        return self.modes[self.mode]

    @property
    def landed_state(self) -> int:
        if self.takeoff_target is not None and self.armed:
            return TAKEOFF
        if not self.armed or self.model.on_ground:
            return ON_GROUND
        if self.mode in self.land_modes:
            return LANDING
        if self.mode in self.rtl_modes and self.rtl_phase == "land":
            return LANDING
        if self.mode == self.auto_mode and self.auto.landing:
            return LANDING
        return IN_AIR

    @property
    def waypoint_radius(self) -> float:
        """Distance (m) at which a mission waypoint counts as reached."""
        return self.settings.waypoint_radius

    def mode_name(self, custom_mode: int) -> str | None:
        for name, value in self.modes.items():
            if value == custom_mode:
                return name
        return None

    def text(self, severity: int, text: str) -> None:
        self.texts.append((severity, text))

    # ---------------------------------------------------------------- commands
    def arm(self, force: bool = False) -> int:
        raise NotImplementedError

    def disarm(self, force: bool = False) -> int:
        if not self.armed:
            return ACCEPTED
        if not self.model.on_ground and not force:
            return self.refuse_disarm_in_air()
        self._disarm("Disarming motors")
        return ACCEPTED

    def refuse_disarm_in_air(self) -> int:
        return FAILED

    def set_mode(self, name: str) -> int:
        raise NotImplementedError

    def takeoff(self, altitude: float) -> int:
        raise NotImplementedError

    def land(self) -> int:
        raise NotImplementedError

    def return_to_launch(self) -> int:
        raise NotImplementedError

    def position_target(self, setpoint: Setpoint) -> None:
        """A SET_POSITION_TARGET_* arrived (already converted to ENU)."""
        raise NotImplementedError

    def reposition(
        self,
        target: tuple[float, float, float],
        *,
        change_mode: bool,
        speed: float | None,
        yaw: float | None,
    ) -> int:
        """MAV_CMD_DO_REPOSITION to the ENU ``target``; returns the MAV_RESULT."""
        raise NotImplementedError

    def guided_goto(self, target: tuple[float, float, float]) -> bool:
        """A guided-mode MISSION_ITEM (current = 2): fly to ``target``; False when the
        vehicle is not in the mode that takes it."""
        return False

    def speed_command(self, kind: int | None, speed: float | None) -> int:
        """MAV_CMD_DO_CHANGE_SPEED from a ground station: ``speed`` None or -1 keeps the
        current speed (PX4)."""
        if speed is None or speed == -1.0:
            return ACCEPTED
        if speed <= 0.0 or kind not in (0, 1, 2, 3):
            return DENIED
        return self.change_speed(kind, speed)

    def change_speed(self, kind: int, speed: float) -> int:
        """MAV_CMD_DO_CHANGE_SPEED: ``kind`` 0/1 horizontal, 2 climb, 3 descent; m/s. Holds
        until the next mode change; a speed below ArduPilot's floor (WPNAV_WP_SPEED_MIN,
        0.2 m/s) changes nothing."""
        m = self.model
        if speed < _MIN_SPEED:
            return ACCEPTED
        if kind in (0, 1):
            self.speed_limit = min(speed, m.max_horizontal_speed)
        elif kind == 2:
            self.climb_limit = min(speed, m.max_climb_speed)
        else:
            self.descent_limit = min(speed, m.max_descent_speed)
        return ACCEPTED

    def terminate(self, on: bool) -> int:
        """MAV_CMD_DO_FLIGHTTERMINATION: ``on`` stops the motors at once, wherever the vehicle
        is (it falls)."""
        return UNSUPPORTED

    def point_yaw(self, heading: float, relative: bool, direction: float) -> int:
        """MAV_CMD_CONDITION_YAW in guided flight: turn to ``heading`` (rad clockwise from
        north), or by it when ``relative``."""
        return UNSUPPORTED

    def set_mission_current(self, seq: int) -> bool:
        """Make item ``seq`` the current one (a completed mission resumes there); False when
        there is no such item to fly."""
        if not self.mission.set_current(seq):
            return False
        self.auto.resume_at_current()
        if self.mode == self.auto_mode and self.armed:
            self.auto.start()
        return True

    def mission_start(self, first: int | None) -> int:
        """MAV_CMD_MISSION_START: fly the stored mission (from item ``first``)."""
        if first is not None and not self.set_mission_current(first):
            return DENIED
        result = self.set_mode(self.auto_mode)
        if result == ACCEPTED and self.armed:
            self.auto.start()
        return result

    def on_mission_complete(self) -> Setpoint:
        """The last mission item is done: what the vehicle does next (hold, or disarm when
        on the ground)."""
        m = self.model
        if self.armed and m.on_ground:
            self._disarm("Mission complete: disarming")
        return Setpoint(position=self.hold, hold_ground=not self.flying)

    def implicit_takeoff_altitude(self) -> float | None:
        """Height (m above home) a mission started on the ground climbs to before its first
        item when that item is not a take-off (PX4), or None (ArduPilot needs a take-off)."""
        return None

    # ------------------------------------------------------------ settings
    def apply_settings(self, settings: SitlSettings) -> None:
        """Fly on validated new settings from now on (a parameter was set)."""
        self.settings = settings
        m = self.model
        m.max_horizontal_speed = settings.max_horizontal_speed
        m.max_climb_speed = settings.max_climb_speed
        m.max_descent_speed = settings.max_descent_speed
        m.max_horizontal_acceleration = settings.max_horizontal_acceleration
        m.max_vertical_acceleration = settings.max_vertical_acceleration
        self.battery.settings = settings.battery

    # ------------------------------------------------------------ mode helpers
    def _arm(self) -> None:
        self.armed = True
        self.model.motors_on = True
        self.took_off = False
        self.flying = False
        self.ground_since = self.time if self.model.on_ground else None
        self.hold = self.model.position
        self.guided = Setpoint(position=self.model.position, hold_ground=True)
        self.home_changed = True  # autopilots (re)set home when arming (send it again)
        # Home moves to where the vehicle arms unless a ground station locked it: ArduPilot's
        # AP_Arming_Copter::arm (ArduCopter/AP_Arming.cpp) calls
        # set_home_to_current_location(false) when home is set and not
        # ahrs.home_is_locked(); PX4's Commander calls set_home_position() on arming when
        # COM_HOME_EN is set and not home_position.manual_home (set by DO_SET_HOME).
        if not self.home_locked:
            x, y = self.estimated_xy()
            if (x, y, self.model.z) != (*self.home_xy, self.home_z):
                self.set_home(x, y, self.model.z)

    def set_home(self, x: float, y: float, z: float, lock: bool = False) -> None:
        """Move home to the ENU point (x, y, z) of the EKF's frame; ``lock``: a ground
        station set it, so arming keeps it (ArduPilot's set_home(loc, lock=true) from
        DO_SET_HOME, PX4's manual_home). RTL flies to the new home from now on."""
        lat, lon = self.geo.to_global(x, y)
        self.home_xy = (x, y)
        self.home_z = z
        self.home_geo = (lat, lon, self.settings.home.alt + z - self.origin_z)
        self.geo.relative_z = z  # MAV_FRAME_GLOBAL_RELATIVE_ALT is above home
        self.home_locked = self.home_locked or lock
        self.home_changed = True

    def _disarm(self, text: str) -> None:
        self.armed = False
        self.model.motors_on = False
        self.flying = False
        self.takeoff_target = None
        self.text(mavlink.MAV_SEVERITY_INFO, text)

    def _enter(self, name: str) -> None:
        """Switch mode: capture the position to hold and reset phase state."""
        old = self.mode
        self.mode = name
        self.hold = self.stopping_point() if name in self.hold_modes else self.model.position
        self.hold_yaw = None
        self.speed_limit = self.climb_limit = self.descent_limit = None
        self.takeoff_target = None
        self.guided = Setpoint(position=self.model.position, hold_ground=not self.flying)
        if name in self.rtl_modes:
            self.begin_return()
        if old == self.auto_mode and name != old:
            self.auto.pause()
        if name == self.auto_mode and name != old and self.armed:
            self.auto.start()

    def stopping_point(self) -> tuple[float, float, float]:
        """Where braking at the horizontal acceleration limit stops the vehicle: what a hold
        mode holds when entered at speed (ArduPilot's LOITER init_target from the position
        controller's stopping point; PX4's Hold from calculate_breaking_stop), so the vehicle
        brakes ahead instead of turning back to where the mode began."""
        m = self.model
        speed = math.hypot(m.vx, m.vy)
        if speed < 1e-3:
            return m.position
        ahead = speed / (2.0 * m.max_horizontal_acceleration)  # v^2 / 2a, over v
        return m.x + m.vx * ahead, m.y + m.vy * ahead, m.z

    @property
    def land_final_speed(self) -> float:
        """Descent speed (m/s) below land_alt_low when landing."""
        return self.settings.land_speed

    def land_setpoint(self, x: float, y: float, agl: float) -> Setpoint:
        """Descend to land at (x, y)."""
        return self._land_setpoint(x, y, agl, self.land_final_speed)

    def lift_off(self) -> None:
        """A mission take-off starts: leave the ground."""
        self.flying = True

    def begin_return(self) -> None:
        """Start a return to launch from here (climb, return, land)."""
        self.hold = self.model.position
        self.rtl_phase = "climb"
        self.rtl_altitude = max(self.model.z, self.home_z + self.settings.rtl_altitude)

    def return_setpoint(self, agl: float) -> Setpoint:
        return self._rtl_setpoint(agl, self.land_final_speed)

    def _land_setpoint(self, x: float, y: float, agl: float, final_speed: float) -> Setpoint:
        s = self.settings
        if agl > s.land_alt_low:
            speed = s.land_speed_high or s.max_descent_speed
        else:
            speed = final_speed
        return Setpoint(position=(x, y, self.model.z - _FAR_BELOW), max_descent=speed)

    def _rtl_setpoint(self, agl: float, final_speed: float) -> Setpoint:
        m = self.model
        if not self.flying:
            return Setpoint(position=self.hold, hold_ground=True)
        if self.rtl_phase == "climb":
            if m.z >= self.rtl_altitude - TAKEOFF_REACHED:
                self.rtl_phase = "return"
            return Setpoint(position=(self.hold[0], self.hold[1], self.rtl_altitude))
        hx, hy = self.home_xy  # RTL returns to the current home
        if self.rtl_phase == "return":
            if math.hypot(m.x - hx, m.y - hy) < _RTL_RADIUS:
                self.rtl_phase = "land"
            return Setpoint(position=(hx, hy, self.rtl_altitude))
        return self._land_setpoint(hx, hy, agl, final_speed)

    # ------------------------------------------------------------- simulation
    def control(self, agl: float) -> Setpoint:
        """The setpoint for the next physics step (mode logic runs here)."""
        raise NotImplementedError

    def disarm_delay(self) -> float:
        """Seconds on the ground, armed, before the autopilot disarms by itself."""
        raise NotImplementedError

    def on_contact(self, contact: Contact) -> None:
        """The vehicle touched the ground: judge the touchdown (crash or landing)."""
        s = self.settings
        slope = float(self.slope(contact.x, contact.y))
        descent = -contact.vz
        self.touchdown = Touchdown(
            contact.x, contact.y, contact.z, contact.speed, descent, slope
        )
        self.flying = False
        self.takeoff_target = None
        self.ground_since = self.time
        if self.mode == self.auto_mode:
            self.auto.on_landed()
        reason = ""
        sideways = math.hypot(contact.vx, contact.vy)
        if descent > s.crash_speed:
            reason = f"hard landing at {descent:.1f} m/s (limit {s.crash_speed:g})"
        elif sideways > s.crash_horizontal_speed:
            reason = f"hit the ground at {sideways:.1f} m/s sideways"
        elif slope > s.crash_slope:
            reason = f"tipped over on a {slope:.0f} deg slope (limit {s.crash_slope:g})"
        if reason:
            self.crashed = True
            self.crash_reason = reason
            self.text(mavlink.MAV_SEVERITY_EMERGENCY, f"Crash: {reason}"[:50])
            if self.armed:
                self._disarm("Crash: Disarming")

    def after_step(self) -> None:
        """Timers that run after each physics step: auto-disarm, liftoff, battery."""
        m = self.model
        if not m.on_ground:
            self.ground_since = None
            if self.armed and not self.took_off:
                self.took_off = True
            self.flying = self.flying or self.armed
        elif self.armed:
            if self.ground_since is None:
                self.ground_since = self.time
            elif self.time - self.ground_since >= self.disarm_delay():
                self._disarm("Disarming motors")
        if self.armed and self.battery.empty:
            self.text(mavlink.MAV_SEVERITY_EMERGENCY, "Battery exhausted: motors stopped")
            self._disarm("Disarming motors")
        self.fence.step()
