"""The telemetry messages the SITL sends, built from the autopilot's state.

One message object per type is kept and refilled in place on each build (cheaper than a new
one); pymavlink packs it again on every send. The streams sent on every tick (ATTITUDE,
LOCAL_POSITION_NED, DISTANCE_SENSOR) also have :attr:`Telemetry.values`: the values their
Struct packs, in wire order, which a link that signs nothing packs without the message
(:meth:`sitl.copter.codec.FastMAVLink.send_values`); the builders fill their message from
the same values, so both give the same bytes.
"""

from __future__ import annotations

import math
import re
import subprocess
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink
from pymavlink.quaternion import QuaternionBase

from . import protocol_version

if TYPE_CHECKING:
    from .server import MavlinkServer

# Telemetry streams a client can ask for, with the MessageRates field of its default rate.
STREAMS: dict[int, str] = {
    mavlink.MAVLINK_MSG_ID_HEARTBEAT: "heartbeat",
    mavlink.MAVLINK_MSG_ID_ATTITUDE: "attitude",
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: "global_position_int",
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: "local_position_ned",
    mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR: "distance_sensor",
    mavlink.MAVLINK_MSG_ID_SYS_STATUS: "sys_status",
    mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: "extended_sys_state",
    mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: "battery_status",
    mavlink.MAVLINK_MSG_ID_HOME_POSITION: "home_position",
    mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: "gps_raw_int",
    mavlink.MAVLINK_MSG_ID_SYSTEM_TIME: "system_time",
    mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: "mission_current",
    mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT: "ekf_status_report",
    mavlink.MAVLINK_MSG_ID_VFR_HUD: "vfr_hud",
    mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: "attitude_quaternion",
    mavlink.MAVLINK_MSG_ID_ALTITUDE: "altitude",
    mavlink.MAVLINK_MSG_ID_FENCE_STATUS: "fence_status",
}
# Messages only one personality sends (EKF_STATUS_REPORT and FENCE_STATUS are ArduPilot's
# dialect; ArduPilot has no ALTITUDE, and no PROTOCOL_VERSION: no ap_message for it).
ONLY = {
    mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT: "ardupilot",
    mavlink.MAVLINK_MSG_ID_FENCE_STATUS: "ardupilot",
    mavlink.MAVLINK_MSG_ID_ALTITUDE: "px4",
    protocol_version.MSG_ID: "px4",
}

_S = mavlink
_SENSORS = (
    _S.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | _S.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | _S.MAV_SYS_STATUS_SENSOR_3D_MAG
    | _S.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | _S.MAV_SYS_STATUS_SENSOR_GPS
    | _S.MAV_SYS_STATUS_SENSOR_LASER_POSITION
    | _S.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | _S.MAV_SYS_STATUS_AHRS
    | _S.MAV_SYS_STATUS_SENSOR_BATTERY
    | _S.MAV_SYS_STATUS_PREARM_CHECK
)
# Reported healthy although absent, as ArduPilot does for what has not failed: ground stations
# (MAVProxy's fence module) read a missing GEOFENCE health bit as a fence breach.
_HEALTHY_ABSENT = _S.MAV_SYS_STATUS_GEOFENCE | _S.MAV_SYS_STATUS_TERRAIN | _S.MAV_SYS_STATUS_LOGGING
_NEEDS_SETTLING = (
    _S.MAV_SYS_STATUS_SENSOR_GPS | _S.MAV_SYS_STATUS_AHRS | _S.MAV_SYS_STATUS_PREARM_CHECK
)
# EKF_STATUS_REPORT flags: attitude and velocities once settled, then an absolute position
# (until then ArduPilot's EKF holds a constant position).
_EKF_SETTLED = (
    _S.EKF_ATTITUDE | _S.EKF_VELOCITY_HORIZ | _S.EKF_VELOCITY_VERT | _S.EKF_POS_HORIZ_REL
    | _S.EKF_POS_VERT_ABS | _S.EKF_PRED_POS_HORIZ_REL
)
_EKF_POSITION = _S.EKF_POS_HORIZ_ABS | _S.EKF_PRED_POS_HORIZ_ABS
_UINT16_MAX = 65535
_INT16_MAX = 32767
# DISTANCE_SENSOR's extension fields, never set here: horizontal and vertical fov, the
# quaternion (spread), signal quality.
_DISTANCE_EXTENSIONS = (0, 0, 0, 0, 0, 0, 0)

# What each personality's AUTOPILOT_VERSION claims: only what this simulator does.
_COMMON_CAPABILITIES = (
    _S.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | _S.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | _S.MAV_PROTOCOL_CAPABILITY_MISSION_INT
    | _S.MAV_PROTOCOL_CAPABILITY_MISSION_FLOAT
    | _S.MAV_PROTOCOL_CAPABILITY_MISSION_FENCE
    | _S.MAV_PROTOCOL_CAPABILITY_MISSION_RALLY
    | _S.MAV_PROTOCOL_CAPABILITY_PARAM_FLOAT
    | _S.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
    | _S.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT
)
CAPABILITIES = {
    "ardupilot": _COMMON_CAPABILITIES | _S.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST,
    "px4": _COMMON_CAPABILITIES | _S.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE,
}
# flight_sw_version: major, minor, patch, release type (0xFF = official).
SOFTWARE_VERSION = {"ardupilot": 0x040500FF, "px4": 0x010F00FF}
# Left zero in AUTOPILOT_VERSION: this simulator has no operating system, board, USB vendor
# and product or hardware UID (uid2) of its own to report.
_NO_HASH = [0] * 8
_NO_UID2 = [0] * 18


@cache
def build_hash() -> str | None:
    """The simulator's own git commit (hex), or None outside a git checkout. The flight
    software a ground station talks to is this code, so AUTOPILOT_VERSION carries its hash,
    never an ArduPilot or PX4 commit."""
    try:
        done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=Path(__file__).parent,
                              capture_output=True, text=True, timeout=10, check=True)
    except (OSError, subprocess.SubprocessError):
        return None
    commit = done.stdout.strip()
    return commit if re.fullmatch(r"[0-9a-f]{40,64}", commit) else None


def custom_versions(personality: str, commit: str | None) -> tuple[list[int], list[int]]:
    """(flight_custom_version, middleware_custom_version) for ``commit``, each autopilot's way.

    ArduPilot (GCS_MAVLINK::send_autopilot_version, GCS_Common.cpp) copies the first 8
    characters of its git hash as text, and no middleware hash. PX4
    (Mavlink::send_autopilot_capabilities, mavlink_main.cpp) stores the first 16 hex digits
    as a little-endian uint64: the flight field keeps its top 5 bytes over a 3-byte vendor
    version (0.0.0 here), the middleware field all 8. QGroundControl and MAVSDK read PX4's
    bytes reversed as hex, ArduPilot's as text (InitialConnectStateMachine)."""
    if commit is None:
        return _NO_HASH, _NO_HASH
    if personality == "px4":
        binary = int(commit[:16], 16)
        return (list((binary & 0xFFFFFFFFFF000000).to_bytes(8, "little")),
                list(binary.to_bytes(8, "little")))
    return list(commit[:8].encode("ascii")), _NO_HASH


class Telemetry:
    """Builds the telemetry of ``server``'s autopilot; :attr:`builders` maps message id to a
    builder returning the message."""

    def __init__(self, server: MavlinkServer) -> None:
        self.server = server
        self.autopilot = ap = server.autopilot
        home = ap.settings.home
        lat, lon = int(home.lat * 1e7), int(home.lon * 1e7)
        alt = int(home.alt * 1000)
        self._heartbeat_msg = mavlink.MAVLink_heartbeat_message(
            mavlink.MAV_TYPE_QUADROTOR, ap.mav_autopilot, 0, 0, 0, 3
        )
        self._attitude_msg = mavlink.MAVLink_attitude_message(0, 0, 0, 0, 0, 0, 0)
        self._gpi_msg = mavlink.MAVLink_global_position_int_message(
            0, lat, lon, alt, 0, 0, 0, 0, 0
        )
        self._lpn_msg = mavlink.MAVLink_local_position_ned_message(0, 0, 0, 0, 0, 0, 0)
        self._distance_msg = mavlink.MAVLink_distance_sensor_message(
            0, 0, 0, 0, mavlink.MAV_DISTANCE_SENSOR_LASER, 0,
            mavlink.MAV_SENSOR_ROTATION_PITCH_270, 0,
        )
        # PX4 reports its pre-arm state in health only, never as present or enabled.
        present = _SENSORS & ~_S.MAV_SYS_STATUS_PREARM_CHECK if ap.name == "px4" else _SENSORS
        self._present = present
        self._sys_status_msg = mavlink.MAVLink_sys_status_message(
            present, present, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
        )
        self._ess_msg = mavlink.MAVLink_extended_sys_state_message(
            mavlink.MAV_VTOL_STATE_UNDEFINED, mavlink.MAV_LANDED_STATE_ON_GROUND
        )
        self._battery_msg = mavlink.MAVLink_battery_status_message(
            0, mavlink.MAV_BATTERY_FUNCTION_ALL, mavlink.MAV_BATTERY_TYPE_LIPO, _INT16_MAX,
            [_UINT16_MAX] * 10, 0, 0, 0, 100,
        )
        self._home_msg = mavlink.MAVLink_home_position_message(
            lat, lon, alt, 0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0
        )
        self._gps_msg = mavlink.MAVLink_gps_raw_int_message(0, 0, lat, lon, alt, 121, 200, 0, 0, 0)
        self._system_time_msg = mavlink.MAVLink_system_time_message(0, 0)
        self._vfr_hud_msg = mavlink.MAVLink_vfr_hud_message(0.0, 0.0, 0, 0, home.alt, 0.0)
        self.builders: dict[int, Callable[[], object]] = {
            mavlink.MAVLINK_MSG_ID_HEARTBEAT: self.heartbeat,
            mavlink.MAVLINK_MSG_ID_ATTITUDE: self._attitude,
            mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: self._global_position_int,
            mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self._local_position_ned,
            mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR: self._distance_sensor,
            mavlink.MAVLINK_MSG_ID_SYS_STATUS: self._sys_status,
            mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: self._extended_sys_state,
            mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: self._battery_status,
            mavlink.MAVLINK_MSG_ID_HOME_POSITION: self._home_position,
            mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: self._gps_raw_int,
            mavlink.MAVLINK_MSG_ID_SYSTEM_TIME: self._system_time,
            mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION: self._autopilot_version,
            protocol_version.MSG_ID: self._protocol_version,
            mavlink.MAVLINK_MSG_ID_MISSION_CURRENT: self.mission_current,
            mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT: self._ekf_status_report,
            mavlink.MAVLINK_MSG_ID_VFR_HUD: self._vfr_hud,
            mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION: self._attitude_quaternion,
            mavlink.MAVLINK_MSG_ID_ALTITUDE: self._altitude,
            # None while no fence is enabled: then ArduPilot sends none.
            mavlink.MAVLINK_MSG_ID_FENCE_STATUS: ap.fence.status_message,
        }
        for msgid, personality in ONLY.items():
            if ap.name != personality:
                del self.builders[msgid]
        self.values: dict[int, Callable[[], tuple]] = {
            mavlink.MAVLINK_MSG_ID_ATTITUDE: self._attitude_values,
            mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: self._local_position_ned_values,
            mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR: self._distance_sensor_values,
        }
        self._attitude_at: tuple[float, float, float, float, float] | None = None
        self._roll_pitch = (0.0, 0.0)

    def _time_ms(self) -> int:
        return int(self.server.time * 1000.0) & 0xFFFFFFFF

    def heartbeat(self):
        ap = self.autopilot
        msg = self._heartbeat_msg
        msg.base_mode = ap.base_mode
        msg.custom_mode = ap.custom_mode
        if ap.crashed:
            msg.system_status = mavlink.MAV_STATE_EMERGENCY
        elif ap.armed:
            msg.system_status = mavlink.MAV_STATE_ACTIVE
        else:
            msg.system_status = mavlink.MAV_STATE_STANDBY
        return msg

    def _roll_pitch_now(self) -> tuple[float, float]:
        """The model's (roll, pitch), computed once for the state it is in (ATTITUDE and
        DISTANCE_SENSOR of the same tick both need it)."""
        m = self.autopilot.model
        at = (m.ax, m.ay, m.az, m.heading, self.server.time)
        if at != self._attitude_at:
            self._attitude_at = at
            self._roll_pitch = m.attitude()
        return self._roll_pitch

    def _attitude_values(self) -> tuple:
        m = self.autopilot.model
        roll, pitch = self._roll_pitch_now()
        msg = self._attitude_msg  # roll and pitch speeds stay as built
        return (self._time_ms(), roll, pitch, m.heading, msg.rollspeed, msg.pitchspeed,
                m.yaw_speed)

    def _attitude(self):
        msg = self._attitude_msg
        (msg.time_boot_ms, msg.roll, msg.pitch, msg.yaw, msg.rollspeed, msg.pitchspeed,
         msg.yawspeed) = self._attitude_values()
        return msg

    def _attitude_quaternion(self):
        """ATTITUDE as a quaternion (w, x, y, z; pymavlink's from roll, pitch, yaw), which
        MAVSDK's attitude_quaternion reads; no display offset (repr_offset_q all zero)."""
        t, roll, pitch, yaw, p, q, r = self._attitude_values()
        w, x, y, z = (float(v) for v in QuaternionBase([roll, pitch, yaw]).q)
        return mavlink.MAVLink_attitude_quaternion_message(t, w, x, y, z, p, q, r, [0.0] * 4)

    def _altitude(self):
        """PX4's ALTITUDE (MAVSDK's telemetry.altitude): AMSL, above home (the local frame's
        origin), and the terrain below from the rangefinder's height above it."""
        ap = self.autopilot
        local = ap.model.z - ap.origin_z
        rel = ap.model.z - ap.home_z
        amsl = ap.settings.home.alt + local
        agl = self.server.agl()
        return mavlink.MAVLink_altitude_message(
            int(self.server.time * 1e6), amsl, amsl, local, rel, amsl - agl, agl
        )

    def _global_position_int(self):
        ap = self.autopilot
        m = ap.model
        msg = self._gpi_msg
        lat, lon = ap.geo.to_global(*ap.estimated_xy())
        rel = m.z - ap.home_z
        msg.time_boot_ms = self._time_ms()
        msg.lat = int(round(lat * 1e7))
        msg.lon = int(round(lon * 1e7))
        msg.alt = int(round((ap.settings.home.alt + m.z - ap.origin_z) * 1000.0))
        msg.relative_alt = int(round(rel * 1000.0))
        msg.vx = int(round(m.vy * 100.0))
        msg.vy = int(round(m.vx * 100.0))
        msg.vz = int(round(-m.vz * 100.0))
        msg.hdg = int(round(math.degrees(m.heading) * 100.0)) % 36000
        return msg

    def _vfr_hud(self):
        # What log viewers plot as the HUD. No airspeed sensor: airspeed is the ground speed,
        # as a copter without one reports before it has a wind estimate. Throttle is a nominal
        # 50 % hover (there are no motors here) plus 10 % per m/s of climb while armed.
        ap = self.autopilot
        m = ap.model
        msg = self._vfr_hud_msg
        speed = math.hypot(m.vx, m.vy)
        msg.airspeed = msg.groundspeed = speed
        msg.heading = int(round(math.degrees(m.heading))) % 360
        msg.throttle = int(min(100.0, max(0.0, 50.0 + 10.0 * m.vz))) if ap.armed else 0
        msg.alt = ap.settings.home.alt + m.z - ap.origin_z
        msg.climb = m.vz
        return msg

    def _local_position_ned_values(self) -> tuple:
        ap = self.autopilot
        m = ap.model
        east, north = ap.estimated_xy()
        return (self._time_ms(), north, east, -(m.z - ap.origin_z), m.vy, m.vx, -m.vz)

    def _local_position_ned(self):
        msg = self._lpn_msg
        (msg.time_boot_ms, msg.x, msg.y, msg.z, msg.vx, msg.vy,
         msg.vz) = self._local_position_ned_values()
        return msg

    def _distance_sensor_values(self) -> tuple:
        s = self.autopilot.settings
        msg = self._distance_msg  # its type, id, orientation and covariance stay as built
        roll, pitch = self._roll_pitch_now()
        tilt = max(math.cos(roll) * math.cos(pitch), 0.1)
        distance = self.server.agl() / tilt
        # Beyond the sensor's range it reports max + 1 cm, as ArduPilot does for "out of range".
        cm = min(max(distance, s.rangefinder_min), s.rangefinder_max + 0.01) * 100.0
        return (self._time_ms(), int(s.rangefinder_min * 100), int(s.rangefinder_max * 100),
                int(round(cm)), msg.type, msg.id, msg.orientation, msg.covariance,
                *_DISTANCE_EXTENSIONS)

    def _distance_sensor(self):
        msg = self._distance_msg
        (msg.time_boot_ms, msg.min_distance, msg.max_distance,
         msg.current_distance) = self._distance_sensor_values()[:4]
        return msg

    def _sys_status(self):
        ap = self.autopilot
        b = ap.battery
        msg = self._sys_status_msg
        health = _SENSORS if ap.settled else _SENSORS & ~_NEEDS_SETTLING
        if ap.gps_lost:
            health &= ~_S.MAV_SYS_STATUS_SENSOR_GPS
        health |= _HEALTHY_ABSENT
        fence = ap.fence.sys_status()
        if fence is not None:  # ArduPilot's (PX4 reports no geofence)
            present, enabled, healthy = fence
            bit = _S.MAV_SYS_STATUS_GEOFENCE
            msg.onboard_control_sensors_present = self._present | bit if present else self._present
            msg.onboard_control_sensors_enabled = self._present | bit if enabled else self._present
            health = health if healthy else health & ~bit
        msg.onboard_control_sensors_health = health
        msg.load = 200
        msg.voltage_battery = int(b.voltage * 1000.0)
        msg.current_battery = int(b.current * 100.0)
        msg.battery_remaining = int(b.percent)
        return msg

    def _extended_sys_state(self):
        msg = self._ess_msg
        msg.landed_state = self.autopilot.landed_state
        return msg

    def _battery_status(self):
        b = self.autopilot.battery
        msg = self._battery_msg
        mv = int(b.voltage * 1000.0)
        msg.voltages = [min(mv, _UINT16_MAX - 1)] + [_UINT16_MAX] * 9
        msg.current_battery = int(b.current * 100.0)
        msg.current_consumed = int(b.consumed_mah)
        msg.energy_consumed = int(b.energy_j / 100.0)
        msg.battery_remaining = int(b.percent)
        return msg

    def _home_position(self):
        """Home as it is now (it moves on arming and with DO_SET_HOME): lat/lon/alt, and
        x, y, z in the local NED frame (about the EKF origin, where the vehicle booted)."""
        ap = self.autopilot
        msg = self._home_msg
        msg.time_usec = int(self.server.time * 1e6)
        lat, lon, alt = ap.home_geo
        msg.latitude, msg.longitude, msg.altitude = int(lat * 1e7), int(lon * 1e7), int(alt * 1000)
        east, north = ap.home_xy
        msg.x, msg.y, msg.z = north, east, ap.origin_z - ap.home_z
        return msg

    def _gps_raw_int(self):
        ap = self.autopilot
        m = ap.model
        msg = self._gps_msg
        msg.time_usec = int(self.server.time * 1e6)
        if ap.gps_lost:
            # No fix: the receiver keeps its last solution and says it is worthless.
            msg.fix_type = mavlink.GPS_FIX_TYPE_NO_FIX
            msg.satellites_visible = 0
            msg.eph = msg.epv = _UINT16_MAX
            return msg
        msg.eph, msg.epv = 121, 200
        lat, lon = ap.geo.to_global(m.x, m.y)
        msg.fix_type = mavlink.GPS_FIX_TYPE_3D_FIX if ap.settled else mavlink.GPS_FIX_TYPE_NO_FIX
        msg.satellites_visible = 12 if ap.settled else 3
        msg.lat = int(round(lat * 1e7))
        msg.lon = int(round(lon * 1e7))
        msg.alt = int(round((ap.settings.home.alt + m.z - ap.origin_z) * 1000.0))
        speed = math.hypot(m.vx, m.vy)
        msg.vel = int(speed * 100.0)
        course = math.degrees(math.atan2(m.vx, m.vy)) % 360.0 if speed > 0.1 else 0.0
        msg.cog = int(course * 100.0) % 36000
        return msg

    def _system_time(self):
        msg = self._system_time_msg
        s = self.autopilot.settings
        msg.time_unix_usec = int((s.unix_time_at_boot + self.server.time) * 1e6)
        msg.time_boot_ms = self._time_ms()
        return msg

    def _autopilot_version(self):
        """What the autopilot is: its capabilities, version and this code's git hash. PX4 also
        reports the flight version as the middleware's, and a uid that differs with the system
        id as PX4 SITL's does; ArduPilot leaves both zero."""
        name = self.autopilot.name
        version = SOFTWARE_VERSION.get(name, 0)
        flight, middleware = custom_versions(name, build_hash())
        px4 = name == "px4"
        return mavlink.MAVLink_autopilot_version_message(
            CAPABILITIES.get(name, _COMMON_CAPABILITIES), version, version if px4 else 0, 0, 0,
            flight, middleware, _NO_HASH, 0, 0,
            self.autopilot.settings.system_id if px4 else 0, _NO_UID2,
        )

    def _protocol_version(self):
        """PX4's PROTOCOL_VERSION (Mavlink::send_protocol_version): MAVLink 2 in use, 1 to 2
        supported; no specification hash, and no library hash (PX4 sends its C library's;
        pymavlink's is not known)."""
        return protocol_version.message_class()(200, 100, 200, _NO_HASH, _NO_HASH)

    def _ekf_status_report(self):
        ap = self.autopilot
        if ap.gps_lost:
            # Dead reckoning: a relative position while velocity aiding lasts, none after.
            flags = _EKF_SETTLED if ap.position_known else _S.EKF_ATTITUDE | _S.EKF_POS_VERT_ABS
        elif ap.position_known:
            flags = _EKF_SETTLED | _EKF_POSITION
        elif ap.settled:
            flags = _EKF_SETTLED | _S.EKF_CONST_POS_MODE
        else:
            flags = _S.EKF_ATTITUDE | _S.EKF_CONST_POS_MODE
        return mavlink.MAVLink_ekf_status_report_message(flags, 0.1, 0.1, 0.1, 0.1, 0.0, 0.0)

    def mission_current(self):
        ap = self.autopilot
        store = ap.mission
        total = len(store.items) - store.first if store.has_mission() else _UINT16_MAX
        # mission_mode: 1 in the mission mode, 2 suspended (any other mode).
        return mavlink.MAVLink_mission_current_message(
            store.current, total, ap.auto.mission_state, 1 if ap.mode == ap.auto_mode else 2
        )
