"""The two autopilot personalities: ArduPilot Copter and PX4 multicopter.

Each mimics the behaviour a driver meets on the real autopilot: the mode numbers in the
HEARTBEAT, what is refused and with which MAV_RESULT and STATUSTEXT, how takeoff, landing and
auto-disarm work. Neither has an RC transmitter, so manual modes hold position.
"""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .autopilot import (
    ACCEPTED,
    DENIED,
    FAILED,
    TAKEOFF_REACHED,
    TEMPORARILY_REJECTED,
    Autopilot,
)
from .fence import ArduPilotFence, Px4Fence
from .kinematics import Setpoint
from .params import ARDUPILOT, PX4

_CRITICAL = mavlink.MAV_SEVERITY_CRITICAL
_INFO = mavlink.MAV_SEVERITY_INFO
_WARNING = mavlink.MAV_SEVERITY_WARNING

# MAV_CMD_COMPONENT_ARM_DISARM param2 magic numbers that skip the checks.
FORCE_ARM = 2989
FORCE_DISARM = 21196


class ArduCopter(Autopilot):
    """ArduPilot Copter: boots in STABILIZE, streams nothing until asked, GUIDED for offboard."""

    name = "ardupilot"
    mav_autopilot = mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    modes = {
        "STABILIZE": 0,
        "ACRO": 1,
        "ALT_HOLD": 2,
        "AUTO": 3,
        "GUIDED": 4,
        "LOITER": 5,
        "RTL": 6,
        "CIRCLE": 7,
        "LAND": 9,
        "POSHOLD": 16,
        "BRAKE": 17,
        "SMART_RTL": 21,
    }
    initial_mode = "STABILIZE"
    hold_modes = frozenset({"STABILIZE", "ALT_HOLD", "LOITER", "POSHOLD", "BRAKE"})
    land_modes = frozenset({"LAND"})
    rtl_modes = frozenset({"RTL", "SMART_RTL"})
    auto_mode = "AUTO"
    home_at_zero = True
    float_frames_on_download = True
    param_table = ARDUPILOT
    fence_class = ArduPilotFence
    # Modes this simulator cannot fly (no pilot sticks): changing to them fails.
    _unflyable = frozenset({"ACRO", "CIRCLE"})
    _not_armable = frozenset({"LAND", "RTL", "SMART_RTL", "AUTO", "CIRCLE"})
    _needs_position = frozenset(
        {"GUIDED", "AUTO", "LOITER", "RTL", "SMART_RTL", "POSHOLD", "BRAKE"}
    )
    _speed_modes = frozenset({"AUTO", "GUIDED", "RTL", "SMART_RTL"})

    @property
    def base_mode(self) -> int:
        flags = (
            mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
            | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
            | mavlink.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED
        )
        if self.mode == "GUIDED":
            flags |= mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.armed:
            flags |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        return flags

    def arm(self, force: bool = False) -> int:
        if self.armed:
            return ACCEPTED
        if self.crashed:
            self.text(_CRITICAL, "PreArm: Crashed, reboot the vehicle")
            return FAILED
        if self.mode in self._not_armable and not self._arming_in_auto_allowed():
            self.text(_CRITICAL, "Arm: Mode not armable")
            return FAILED
        if not force:
            if not self.settled:
                self.text(_CRITICAL, "PreArm: Need Position Estimate")
                return FAILED
            if self.battery.empty:
                self.text(_CRITICAL, "PreArm: Battery 1 below minimum capacity")
                return FAILED
            if self.mode in self._needs_position and not self.position_known:
                self.text(_CRITICAL, "Arm: Need Position Estimate")
                return FAILED
            fence = self.fence.prearm_failure()  # AP_Arming::fence_checks
            if fence:
                self.text(_CRITICAL, f"PreArm: {fence}")
                return FAILED
        self._arm()
        self.text(_INFO, "Arming motors")  # AP_Arming_Copter::arm, in SITL builds
        return ACCEPTED

    def set_mode(self, name: str) -> int:
        if name not in self.modes or name in self._unflyable:
            self.text(_WARNING, "Flight mode change failed")
            return FAILED
        if name in self._needs_position and not self.position_known:
            self.text(_WARNING, f"Mode change to {name} failed: requires position")
            return FAILED
        if name == "AUTO" and name != self.mode and not self._auto_can_start():
            self.text(_WARNING, "Mode change to AUTO failed: init failed")
            return FAILED
        if name != self.mode:
            self._enter(name)
        return ACCEPTED

    def _arming_in_auto_allowed(self) -> bool:
        # AUTO_OPTIONS bit 0: "allow arming" in AUTO.
        return self.mode == "AUTO" and int(self.params.stored("AUTO_OPTIONS")) & 1 == 1

    def _auto_can_start(self) -> bool:
        """ModeAuto::init: a mission to fly, and a take-off first when armed on the ground."""
        if not self.mission.has_mission():
            return False
        first = self.mission.items[self.mission.current]
        if self.armed and self.model.on_ground and first.command != mavlink.MAV_CMD_NAV_TAKEOFF:
            self.text(_CRITICAL, "Auto: Missing Takeoff Cmd")
            return False
        return True

    def takeoff(self, altitude: float) -> int:
        # ArduPilot's do_user_takeoff: armed, in GUIDED, still on the ground, target above.
        m = self.model
        if not self.armed or self.mode != "GUIDED" or self.flying:
            return FAILED
        if not math.isfinite(altitude) or self.home_z + altitude <= m.z:
            return FAILED
        self.takeoff_target = self.home_z + altitude
        self.flying = True
        self.guided = Setpoint(position=(m.x, m.y, self.takeoff_target))
        return ACCEPTED

    def land(self) -> int:
        return self.set_mode("LAND")

    def return_to_launch(self) -> int:
        return self.set_mode("RTL")

    def speed_command(self, kind: int | None, speed: float | None) -> int:
        # GCS_MAVLINK_Copter::handle_MAV_CMD_DO_CHANGE_SPEED: a speed that is not positive
        # (-1, NaN) is denied; only AUTO, GUIDED and RTL (SMART_RTL is an RTL) have a speed
        # to set (Mode::set_speed_xy_cms and its kin), every other mode fails it.
        if speed is None or speed <= 0.0 or kind == 4:  # 4: SPEED_TYPE_ENUM_END
            return DENIED
        if kind not in (0, 1, 2, 3) or self.mode not in self._speed_modes:
            return FAILED
        return self.change_speed(kind, speed)

    def terminate(self, on: bool) -> int:
        # GCS_MAVLINK_Copter::handle_flight_termination (no advanced failsafe): a disarm,
        # in flight too; param1 <= 0.5 fails.
        if not on:
            return FAILED
        if self.armed:
            self._disarm("Disarming motors")
        return ACCEPTED

    def position_target(self, setpoint: Setpoint) -> None:
        # Honoured in GUIDED only; a takeoff in progress is overridden, as on ArduPilot.
        if self.mode != "GUIDED":
            return
        if setpoint.position is not None and not self.fence.allows(setpoint.position):
            return  # ModeGuided::set_destination refuses a point beyond the fence
        setpoint.hold_ground = not self.flying
        if setpoint.hold_ground:
            # On the ground without a takeoff: accepted but not flown.
            setpoint.position = self.guided.position
            setpoint.velocity = None
        self.guided = setpoint
        self.takeoff_target = None
        if setpoint.position is None and setpoint.velocity is not None:
            self.guided_velocity_time = self.time

    def reposition(self, target, *, change_mode, speed, yaw) -> int:
        # GCS_MAVLINK_Copter::handle_command_int_do_reposition
        if self.mode != "GUIDED":
            if not change_mode:
                return DENIED
            if self.set_mode("GUIDED") != ACCEPTED:
                return FAILED
        if not self.fence.allows(target):
            return FAILED  # set_destination refused it (beyond the fence)
        if speed is not None:
            self.change_speed(1, speed)
        self.position_target(Setpoint(position=target, yaw=yaw))
        return ACCEPTED

    def guided_goto(self, target) -> bool:
        if self.mode != "GUIDED" or not self.fence.allows(target):
            return False
        self.position_target(Setpoint(position=target))
        return True

    def point_yaw(self, heading: float, relative: bool, direction: float) -> int:
        if self.mode not in ("GUIDED", "AUTO") or not self.flying:
            return FAILED
        if relative:
            heading = self.model.heading + direction * heading
        self.guided.yaw = (heading + math.pi) % (2.0 * math.pi) - math.pi
        return ACCEPTED

    def control(self, agl: float) -> Setpoint:
        m = self.model
        mode = self.mode
        if mode == "AUTO":
            return self.auto.setpoint(agl)
        if mode == "GUIDED":
            sp = self.guided
            sp.max_speed = self.speed_limit
            sp.max_climb = self.climb_limit
            sp.max_descent = self.descent_limit
            if self.takeoff_target is not None and m.z >= self.takeoff_target - TAKEOFF_REACHED:
                self.takeoff_target = None
            if (
                sp.position is None
                and sp.velocity is not None
                and self.time - self.guided_velocity_time > self.settings.guided_velocity_timeout
            ):
                # A velocity target not refreshed: ArduPilot stops and holds.
                self.guided = sp = Setpoint(position=m.position, hold_ground=sp.hold_ground)
            return sp
        if mode in self.land_modes:
            return self._land_setpoint(self.hold[0], self.hold[1], agl, self.settings.land_speed)
        if mode in self.rtl_modes:
            return self._rtl_setpoint(agl, self.settings.land_speed)
        return Setpoint(position=self.hold, hold_ground=not self.flying)

    def on_gps_lost(self) -> None:
        # EKF3 falls back to optical flow when it has it (EK3_SRC1_VELXY), else stops aiding.
        aided = self.gps is not None and self.gps.settings.velocity_aiding
        self.text(_INFO, "EKF3 IMU0 is using optical flow" if aided else "EKF3 IMU0 stopped aiding")

    def on_position_failed(self) -> None:
        # ekf_check: bad position variance for 1 s -> EKF failsafe, FS_EKF_ACTION 1 (Land) in a
        # mode that needs a position; other modes keep flying (nothing to fly without one).
        self.text(_CRITICAL, "EKF variance")
        if self.mode in self._needs_position and self.armed:
            self._enter("LAND")
            self.text(_CRITICAL, "EKF Failsafe: changed to LAND Mode")

    def disarm_delay(self) -> float:
        landing = self.mode in self.land_modes or self.mode in self.rtl_modes
        if landing and self.took_off:
            return self.settings.land_disarm_delay
        return self.settings.disarm_delay


def px4_custom_mode(main_mode: int, sub_mode: int = 0) -> int:
    """PX4's HEARTBEAT custom_mode: (main_mode << 16) | (sub_mode << 24)."""
    return (main_mode << 16) | (sub_mode << 24)


class Px4Copter(Autopilot):
    """PX4 multicopter: idles in AUTO.LOITER, streams by itself, OFFBOARD needs a setpoint
    stream before and during the mode, takeoff and landing through AUTO modes."""

    name = "px4"
    mav_autopilot = mavlink.MAV_AUTOPILOT_PX4
    modes = {
        "MANUAL": px4_custom_mode(1),
        "ALTCTL": px4_custom_mode(2),
        "POSCTL": px4_custom_mode(3),
        "AUTO.READY": px4_custom_mode(4, 1),
        "AUTO.TAKEOFF": px4_custom_mode(4, 2),
        "AUTO.LOITER": px4_custom_mode(4, 3),
        "AUTO.MISSION": px4_custom_mode(4, 4),
        "AUTO.RTL": px4_custom_mode(4, 5),
        "AUTO.LAND": px4_custom_mode(4, 6),
        "ACRO": px4_custom_mode(5),
        "OFFBOARD": px4_custom_mode(6),
        "STABILIZED": px4_custom_mode(7),
    }
    initial_mode = "AUTO.LOITER"
    hold_modes = frozenset(
        {"MANUAL", "ALTCTL", "POSCTL", "AUTO.LOITER", "AUTO.READY", "STABILIZED"}
    )
    land_modes = frozenset({"AUTO.LAND"})
    rtl_modes = frozenset({"AUTO.RTL"})
    auto_mode = "AUTO.MISSION"
    announces_mission_current = True
    param_table = PX4
    param_bytewise = True
    fence_class = Px4Fence
    _unflyable = frozenset({"ACRO"})
    _needs_position = frozenset(
        {"POSCTL", "AUTO.LOITER", "AUTO.TAKEOFF", "AUTO.RTL", "OFFBOARD"}
    )

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.last_setpoint_time = -math.inf
        self.terminated = False  # a flight termination holds until reboot
        self.offboard = Setpoint(position=self.model.position, hold_ground=True)

    @property
    def base_mode(self) -> int:
        # PX4 without an RC receiver sets no MANUAL_INPUT flag (29 in Hold, as PX4 SITL).
        flags = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED | mavlink.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.mode.startswith("AUTO"):
            flags |= mavlink.MAV_MODE_FLAG_AUTO_ENABLED | mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.mode == "OFFBOARD":
            flags |= mavlink.MAV_MODE_FLAG_GUIDED_ENABLED
        if self.armed:
            flags |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        return flags

    def arm(self, force: bool = False) -> int:
        if self.armed:
            return ACCEPTED
        if self.crashed:
            self.text(_CRITICAL, "Arming denied: vehicle crashed")
            return TEMPORARILY_REJECTED
        if not force:
            if self.terminated:
                self.text(_CRITICAL, "Preflight Fail: Flight termination active")
                return TEMPORARILY_REJECTED
            if not self.settled:
                self.text(_CRITICAL, "Preflight Fail: ekf2 not ready")
                return TEMPORARILY_REJECTED
            if self.battery.empty:
                self.text(_CRITICAL, "Preflight Fail: low battery")
                return TEMPORARILY_REJECTED
            fence = self.fence.prearm_failure()
            if fence:
                self.text(_CRITICAL, fence)
                return TEMPORARILY_REJECTED
        self._arm()
        self.text(_INFO, "Armed by external command")
        if self.mode == self.auto_mode:
            self.auto.start()  # armed in mission mode: the mission takes off
        return ACCEPTED

    def refuse_disarm_in_air(self) -> int:
        self.text(_CRITICAL, "Disarming denied: not landed")
        return TEMPORARILY_REJECTED

    def _stream_alive(self) -> bool:
        """The latest setpoint is younger than COM_OF_LOSS_T: all PX4 asks of the stream
        (commander's OffboardChecks); a rate is only what its docs advise (> 2 Hz)."""
        return self.time - self.last_setpoint_time <= self.settings.offboard_loss_timeout

    def set_mode(self, name: str) -> int:
        if name not in self.modes or name in self._unflyable:
            self.text(_CRITICAL, f"Switching to {name} is currently not possible")
            return TEMPORARILY_REJECTED
        if name in self._needs_position and not self.position_known:
            self.text(_CRITICAL, f"Switching to {name} is currently not possible")
            return TEMPORARILY_REJECTED
        if name == "OFFBOARD":
            # Accepted, but PX4 only switches if setpoints are already streaming.
            if not self._stream_alive():
                self.text(_CRITICAL, "Switching to Offboard is currently not possible")
                return ACCEPTED
            if self.mode == self.auto_mode:
                self.auto.pause()
            self.mode = "OFFBOARD"
            self.takeoff_target = None
            return ACCEPTED
        if name == "AUTO.TAKEOFF":
            return self.takeoff(math.nan)
        if name != self.mode:
            self._enter(name)
        return ACCEPTED

    def takeoff(self, altitude: float) -> int:
        """MAV_CMD_NAV_TAKEOFF: ``altitude`` is param7, metres AMSL (NaN = default height)."""
        m = self.model
        if not self.armed:
            self.text(_CRITICAL, "Takeoff denied: disarmed")
            return TEMPORARILY_REJECTED
        if self.flying:
            return TEMPORARILY_REJECTED
        if math.isfinite(altitude):
            target = altitude - self.settings.home.alt
        else:
            target = m.z + self.settings.px4_takeoff_altitude
        if target <= m.z:
            return TEMPORARILY_REJECTED
        self._enter("AUTO.TAKEOFF")
        self.takeoff_target = target
        self.flying = True
        self.hold = (m.x, m.y, target)
        self.text(_INFO, "Takeoff detected")
        return ACCEPTED

    def land(self) -> int:
        if self.mode != "AUTO.LAND":
            self._enter("AUTO.LAND")
        return ACCEPTED

    def return_to_launch(self) -> int:
        return self.set_mode("AUTO.RTL")

    def terminate(self, on: bool) -> int:
        # Commander, DO_FLIGHTTERMINATION: param1 > 0.5 sets the outputs to their failsafe
        # values (motors off) until reboot; the vehicle stays armed until the land detector's
        # auto-disarm. param1 <= 0.5 lifts it. Accepted either way.
        self.terminated = on
        if on:
            self.model.motors_on = False
        elif self.armed:
            self.model.motors_on = True
        return ACCEPTED

    def position_target(self, setpoint: Setpoint) -> None:
        # Recorded in any mode (that is how OFFBOARD sees the stream); flown in OFFBOARD.
        self.last_setpoint_time = self.time
        setpoint.hold_ground = False
        self.offboard = setpoint

    def reposition(self, target, *, change_mode, speed, yaw) -> int:
        # Commander switches to Hold (AUTO.LOITER) when asked; the navigator flies the Hold
        # point to the target.
        if change_mode and self.mode != "AUTO.LOITER":
            result = self.set_mode("AUTO.LOITER")
            if result != ACCEPTED:
                return result
        if self.mode == "AUTO.LOITER":
            if speed is not None:
                self.change_speed(1, speed)
            self.hold = target
            self.hold_yaw = yaw
        return ACCEPTED

    def on_mission_complete(self) -> Setpoint:
        if self.flying:
            self.text(_INFO, "Mission finished, loitering")
            self._enter("AUTO.LOITER")
        return Setpoint(position=self.hold, hold_ground=not self.flying)

    def implicit_takeoff_altitude(self) -> float | None:
        return self.settings.px4_takeoff_altitude

    @property
    def land_final_speed(self) -> float:
        return self.settings.px4_land_speed

    def control(self, agl: float) -> Setpoint:
        m = self.model
        s = self.settings
        mode = self.mode
        if mode == self.auto_mode:
            return self.auto.setpoint(agl)
        if mode == "OFFBOARD":
            if self._stream_alive():
                return self.offboard
            # COM_OBL_RC_ACT 0 asks for Position, which needs manual control; with no RC the
            # failsafe falls through Altitude and Stabilized to Hold (commander's
            # FailsafeBase, its fallback chain).
            self.text(_CRITICAL, "Failsafe: offboard signal lost, switching to Hold")
            self._enter("AUTO.LOITER")
            mode = self.mode
        if mode == "AUTO.TAKEOFF":
            if self.takeoff_target is not None and m.z >= self.takeoff_target - TAKEOFF_REACHED:
                self.mode = "AUTO.LOITER"
                self.takeoff_target = None
            return Setpoint(position=self.hold)
        if mode in self.land_modes:
            return self._land_setpoint(self.hold[0], self.hold[1], agl, s.px4_land_speed)
        if mode in self.rtl_modes:
            return self._rtl_setpoint(agl, s.px4_land_speed)
        return Setpoint(position=self.hold, yaw=self.hold_yaw, max_speed=self.speed_limit,
                        hold_ground=not self.flying)

    def on_gps_lost(self) -> None:
        self.text(_INFO, "GNSS data lost")

    def on_position_failed(self) -> None:
        # COM_POS_FS_DELAY after the local position became invalid: a mode that needs it
        # fails over to Land (descend on altitude alone).
        needs = self.mode in self._needs_position or self.mode == self.auto_mode
        if needs and self.armed and self.flying:
            self.text(_CRITICAL, "Failsafe activated: no local position, landing")
            self._enter("AUTO.LAND")

    def disarm_delay(self) -> float:
        # COM_DISARM_LAND after a landing, COM_DISARM_PRFLT if it never took off.
        if self.took_off:
            return self.settings.px4_land_disarm_delay
        return self.settings.disarm_delay


PERSONALITIES: dict[str, type[Autopilot]] = {"ardupilot": ArduCopter, "px4": Px4Copter}
