"""The SITL's MAVLink side: links, message handling and the telemetry scheduler.

A :class:`MavlinkServer` serves any number of links (anything with ``read() -> bytes`` and
``write(bytes)``). Per link it keeps a pymavlink parser, a sequence counter and its own message
intervals, as ArduPilot keeps them per channel. Incoming bytes are parsed with pymavlink's
robust parser (corrupt bytes are skipped and counted); outgoing messages are packed by
pymavlink into one buffer per link and written once per step.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .autopilot import ACCEPTED, FAILED, UNSUPPORTED, Autopilot
from .geo import LocalToGlobal, ned_to_enu
from .kinematics import Setpoint
from .personalities import FORCE_ARM, FORCE_DISARM

# Telemetry the server can build, with the MessageRates field giving its default rate.
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
}

# Legacy REQUEST_DATA_STREAM groups (MAVProxy and older GCSs still use them).
_DATA_STREAMS: dict[int, tuple[int, ...]] = {
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: (
        mavlink.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
    ),
    mavlink.MAV_DATA_STREAM_POSITION: (
        mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    ),
    mavlink.MAV_DATA_STREAM_EXTRA1: (mavlink.MAVLINK_MSG_ID_ATTITUDE,),
    mavlink.MAV_DATA_STREAM_EXTRA3: (
        mavlink.MAVLINK_MSG_ID_BATTERY_STATUS,
        mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR,
        mavlink.MAVLINK_MSG_ID_SYSTEM_TIME,
    ),
}
_DATA_STREAMS[mavlink.MAV_DATA_STREAM_ALL] = tuple(
    m for group in _DATA_STREAMS.values() for m in group
)

_IGNORE_POSITION = (
    mavlink.POSITION_TARGET_TYPEMASK_X_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_Y_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_Z_IGNORE
)
_IGNORE_VELOCITY = (
    mavlink.POSITION_TARGET_TYPEMASK_VX_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_VY_IGNORE
    | mavlink.POSITION_TARGET_TYPEMASK_VZ_IGNORE
)
_IGNORE_YAW = mavlink.POSITION_TARGET_TYPEMASK_YAW_IGNORE
_IGNORE_YAW_RATE = mavlink.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE

_SENSORS = (
    mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL
    | mavlink.MAV_SYS_STATUS_SENSOR_3D_MAG
    | mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE
    | mavlink.MAV_SYS_STATUS_SENSOR_GPS
    | mavlink.MAV_SYS_STATUS_SENSOR_LASER_POSITION
    | mavlink.MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS
    | mavlink.MAV_SYS_STATUS_AHRS
    | mavlink.MAV_SYS_STATUS_SENSOR_BATTERY
    | mavlink.MAV_SYS_STATUS_PREARM_CHECK
)
_NEEDS_SETTLING = (
    mavlink.MAV_SYS_STATUS_SENSOR_GPS
    | mavlink.MAV_SYS_STATUS_AHRS
    | mavlink.MAV_SYS_STATUS_PREARM_CHECK
)
_CAPABILITIES = (
    mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    | mavlink.MAV_PROTOCOL_CAPABILITY_COMMAND_INT
    | mavlink.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_LOCAL_NED
)
_UINT16_MAX = 65535
_INT16_MAX = 32767


class _Outbox:
    """File-like sink for pymavlink: collects the packets of one step."""

    __slots__ = ("chunks",)

    def __init__(self) -> None:
        self.chunks: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.chunks.append(data)


class Link:
    """One MAVLink peer: its endpoint, parser, sequence counter and stream intervals."""

    def __init__(self, endpoint, system_id: int, component_id: int) -> None:
        self.endpoint = endpoint
        self.outbox = _Outbox()
        self.mav = mavlink.MAVLink(self.outbox, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.open = False  # a packet has arrived (ArduPilot talks only then)
        self.intervals: dict[int, float] = {}  # msgid -> seconds
        self.next_due: dict[int, float] = {}
        self.once: list[int] = []
        self.home_sent = False
        self.packets_received = 0
        self.corrupt_packets = 0
        self.corrupt_bytes = 0

    @property
    def closed(self) -> bool:
        return bool(getattr(self.endpoint, "closed", False))

    def set_interval(self, msgid: int, interval: float, now: float) -> None:
        """Stream ``msgid`` every ``interval`` s (<= 0 or inf: stop)."""
        if interval <= 0.0 or not math.isfinite(interval):
            self.intervals.pop(msgid, None)
            self.next_due.pop(msgid, None)
            return
        self.intervals[msgid] = interval
        self.next_due[msgid] = now

    def flush(self) -> None:
        chunks = self.outbox.chunks
        if chunks:
            self.endpoint.write(b"".join(chunks))
            chunks.clear()


class MavlinkServer:
    """Answers commands and streams telemetry for one simulated :class:`Autopilot`.

    Args:
        autopilot: the flight logic it serves.
        agl: callable returning the vehicle's height above the terrain (m) for the
            rangefinder.
        streams_by_default: stream ``rates`` on a link as soon as it is attached (PX4) rather
            than only HEARTBEAT after the first packet arrives (ArduPilot).
    """

    def __init__(
        self, autopilot: Autopilot, agl: Callable[[], float], *, streams_by_default: bool
    ) -> None:
        self.autopilot = autopilot
        self.settings = s = autopilot.settings
        self.agl = agl
        self.streams_by_default = streams_by_default
        self.links: list[Link] = []
        self.time = 0.0
        self.to_global = LocalToGlobal(s.home.lat, s.home.lon)
        self.default_intervals = {
            msgid: 1.0 / getattr(s.rates, name)
            for msgid, name in STREAMS.items()
            if getattr(s.rates, name) > 0
        }
        self.ignored_setpoints = 0
        self._builders: dict[int, Callable[[], object]] = {
            mavlink.MAVLINK_MSG_ID_HEARTBEAT: self._heartbeat,
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
        }
        self._handlers: dict[str, Callable[[Link, object], None]] = {
            "COMMAND_LONG": self._on_command_long,
            "COMMAND_INT": self._on_command_int,
            "SET_MODE": self._on_set_mode,
            "SET_POSITION_TARGET_LOCAL_NED": self._on_position_target,
            "REQUEST_DATA_STREAM": self._on_request_data_stream,
        }
        self._prebuilt = self._prebuild()
        self._cache: dict[int, object] = {}

    # ------------------------------------------------------------------ links
    def attach(self, endpoint) -> Link:
        link = Link(endpoint, self.settings.system_id, self.settings.component_id)
        self.links.append(link)
        if self.streams_by_default:
            self._open(link)
        return link

    def detach(self, endpoint) -> None:
        self.links = [link for link in self.links if link.endpoint is not endpoint]

    def _open(self, link: Link) -> None:
        link.open = True
        if self.streams_by_default:
            for msgid, interval in self.default_intervals.items():
                link.set_interval(msgid, interval, self.time)
        else:
            link.set_interval(mavlink.MAVLINK_MSG_ID_HEARTBEAT, 1.0, self.time)

    @property
    def corrupt_bytes(self) -> int:
        return sum(link.corrupt_bytes for link in self.links)

    # ---------------------------------------------------------------- receive
    def receive(self) -> None:
        """Read and handle everything that arrived on every link."""
        self.links = [link for link in self.links if not link.closed]
        for link in self.links:
            data = link.endpoint.read()
            if not data:
                continue
            msgs = link.mav.parse_buffer(data)
            if not msgs:
                continue
            for msg in msgs:
                name = msg.get_type()
                if name == "BAD_DATA":
                    link.corrupt_packets += 1
                    link.corrupt_bytes += len(msg.data)
                    continue
                link.packets_received += 1
                if not link.open:
                    self._open(link)
                handler = self._handlers.get(name)
                if handler is not None and self._for_me(msg):
                    handler(link, msg)

    def _for_me(self, msg) -> bool:
        s = self.settings
        system = getattr(msg, "target_system", 0)
        component = getattr(msg, "target_component", 0)
        return system in (0, s.system_id) and component in (0, s.component_id)

    def _send(self, link: Link, msg) -> None:
        link.mav.send(msg)

    def _send_texts(self) -> None:
        texts = self.autopilot.texts
        if not texts:
            return
        for severity, text in texts:
            msg = mavlink.MAVLink_statustext_message(severity, text.encode()[:50])
            for link in self.links:
                if link.open:
                    link.mav.send(msg)
        texts.clear()

    def _ack(self, link: Link, command: int, result: int, msg=None) -> None:
        self._send_texts()  # the reason (PreArm: ...) goes out before the ACK, as on ArduPilot
        ack = mavlink.MAVLink_command_ack_message(
            command,
            result,
            0,
            0,
            msg.get_srcSystem() if msg is not None else 0,
            msg.get_srcComponent() if msg is not None else 0,
        )
        link.mav.send(ack)

    def _on_command_long(self, link: Link, msg) -> None:
        params = (
            msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7
        )
        self._ack(link, msg.command, self._command(link, msg.command, params), msg)

    def _on_command_int(self, link: Link, msg) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
        self._ack(link, msg.command, self._command(link, msg.command, params), msg)

    def _command(self, link: Link, command: int, p: tuple[float, ...]) -> int:
        ap = self.autopilot
        if command == mavlink.MAV_CMD_SET_MESSAGE_INTERVAL:
            msgid = int(p[0])
            if p[1] == 0:
                interval = self.default_intervals.get(msgid, 0.0)
            elif p[1] < 0:
                interval = 0.0
            else:
                interval = p[1] * 1e-6
            if msgid in STREAMS:
                link.set_interval(msgid, interval, self.time)
            return ACCEPTED  # ArduPilot ACKs every interval request
        if command == mavlink.MAV_CMD_GET_MESSAGE_INTERVAL:
            msgid = int(p[0])
            interval = link.intervals.get(msgid)
            us = int(interval * 1e6) if interval else (-1 if msgid in STREAMS else 0)
            link.mav.send(mavlink.MAVLink_message_interval_message(msgid, us))
            return ACCEPTED
        if command == mavlink.MAV_CMD_REQUEST_MESSAGE:
            msgid = int(p[0])
            if msgid not in self._builders:
                return UNSUPPORTED
            link.once.append(msgid)
            return ACCEPTED
        if command == mavlink.MAV_CMD_GET_HOME_POSITION:
            link.once.append(mavlink.MAVLINK_MSG_ID_HOME_POSITION)
            return ACCEPTED
        if command == mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            link.once.append(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
            return ACCEPTED
        if command == mavlink.MAV_CMD_COMPONENT_ARM_DISARM:
            if p[0] == 1:
                return ap.arm(force=int(p[1]) == FORCE_ARM)
            if p[0] == 0:
                return ap.disarm(force=int(p[1]) == FORCE_DISARM)
            return FAILED
        if command == mavlink.MAV_CMD_NAV_TAKEOFF:
            return ap.takeoff(p[6])
        if command == mavlink.MAV_CMD_NAV_LAND:
            return ap.land()
        if command == mavlink.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return ap.return_to_launch()
        if command == mavlink.MAV_CMD_DO_SET_MODE:
            return self._set_mode(int(p[0]), p[1], p[2])
        return UNSUPPORTED

    def _set_mode(self, base_mode: int, param2: float, param3: float) -> int:
        """DO_SET_MODE: ArduPilot's custom mode is param2; PX4's main/sub modes are param2/3."""
        ap = self.autopilot
        if not base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return UNSUPPORTED
        if ap.name == "px4":
            custom = (int(param2) << 16) | (int(param3) << 24)
        else:
            custom = int(param2)
        return self._mode_by_number(custom)

    def _mode_by_number(self, custom_mode: int) -> int:
        ap = self.autopilot
        name = ap.mode_name(custom_mode)
        if name is None:
            return ap.set_mode(f"mode {custom_mode}")
        return ap.set_mode(name)

    def _on_set_mode(self, link: Link, msg) -> None:
        if not msg.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            result = UNSUPPORTED
        else:
            result = self._mode_by_number(msg.custom_mode)
        # ArduPilot ACKs SET_MODE with the message id (11) as the command.
        self._ack(link, mavlink.MAVLINK_MSG_ID_SET_MODE, result, msg)

    def _on_position_target(self, link: Link, msg) -> None:
        ap = self.autopilot
        m = ap.model
        mask = msg.type_mask
        frame = msg.coordinate_frame
        if frame not in (mavlink.MAV_FRAME_LOCAL_NED, mavlink.MAV_FRAME_LOCAL_OFFSET_NED):
            self.ignored_setpoints += 1
            return
        position = velocity = None
        if not mask & _IGNORE_POSITION:
            e, n, u = ned_to_enu(msg.x, msg.y, msg.z)
            if frame == mavlink.MAV_FRAME_LOCAL_NED:
                position = (e, n, u + ap.home_z)
            else:
                position = (m.x + e, m.y + n, m.z + u)
        if not mask & _IGNORE_VELOCITY:
            velocity = ned_to_enu(msg.vx, msg.vy, msg.vz)
        values = (*(position or ()), *(velocity or ()))
        if not all(math.isfinite(v) for v in values):
            self.ignored_setpoints += 1
            return
        yaw = None if mask & _IGNORE_YAW or not math.isfinite(msg.yaw) else msg.yaw
        yaw_rate = None
        if not mask & _IGNORE_YAW_RATE and math.isfinite(msg.yaw_rate):
            yaw_rate = msg.yaw_rate
        if position is None and velocity is None:
            if yaw is None and yaw_rate is None:
                self.ignored_setpoints += 1
                return
            position = m.position  # a yaw-only target holds position
        ap.position_target(
            Setpoint(position=position, velocity=velocity, yaw=yaw, yaw_rate=yaw_rate)
        )

    def _on_request_data_stream(self, link: Link, msg) -> None:
        group = _DATA_STREAMS.get(msg.req_stream_id, ())
        rate = msg.req_message_rate if msg.start_stop else 0
        for msgid in group:
            link.set_interval(msgid, 1.0 / rate if rate > 0 else 0.0, self.time)

    # ------------------------------------------------------------------- emit
    def emit(self, now: float) -> None:
        """Send the STATUSTEXTs and every telemetry message due at ``now``; flush links."""
        self.time = now
        ap = self.autopilot
        self._send_texts()
        cache = self._cache
        cache.clear()
        home_msg = mavlink.MAVLINK_MSG_ID_HOME_POSITION
        for link in self.links:
            if not link.open:
                continue
            if ap.settled and (not link.home_sent or ap.home_changed):
                link.once.append(home_msg)
            once = link.once
            for msgid in once:
                if msgid == home_msg:
                    link.home_sent = True
                link.mav.send(self._build(msgid))
            once.clear()
            due = link.next_due
            for msgid, when in due.items():
                if now + 1e-9 >= when:
                    if msgid == home_msg and not ap.settled:
                        continue  # no home until the EKF has a position
                    msg = cache.get(msgid)
                    if msg is None:
                        msg = cache[msgid] = self._build(msgid)
                    link.mav.send(msg)
                    nxt = when + link.intervals[msgid]
                    due[msgid] = nxt if nxt > now else now + link.intervals[msgid]
            link.flush()
        if ap.settled:
            ap.home_changed = False

    def _build(self, msgid: int):
        return self._builders[msgid]()

    # --------------------------------------------------------------- messages
    def _prebuild(self) -> dict[str, object]:
        """One message object per type, refilled in place each time (cheaper than new ones)."""
        s = self.settings
        lat, lon = int(s.home.lat * 1e7), int(s.home.lon * 1e7)
        alt = int(s.home.alt * 1000)
        return {
            "heartbeat": mavlink.MAVLink_heartbeat_message(
                mavlink.MAV_TYPE_QUADROTOR, self.autopilot.mav_autopilot, 0, 0, 0, 3
            ),
            "attitude": mavlink.MAVLink_attitude_message(0, 0, 0, 0, 0, 0, 0),
            "gpi": mavlink.MAVLink_global_position_int_message(0, lat, lon, alt, 0, 0, 0, 0, 0),
            "lpn": mavlink.MAVLink_local_position_ned_message(0, 0, 0, 0, 0, 0, 0),
            "distance": mavlink.MAVLink_distance_sensor_message(
                0,
                int(s.rangefinder_min * 100),
                int(s.rangefinder_max * 100),
                0,
                mavlink.MAV_DISTANCE_SENSOR_LASER,
                0,
                mavlink.MAV_SENSOR_ROTATION_PITCH_270,
                0,
            ),
            "sys_status": mavlink.MAVLink_sys_status_message(
                _SENSORS, _SENSORS, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0
            ),
            "ess": mavlink.MAVLink_extended_sys_state_message(
                mavlink.MAV_VTOL_STATE_UNDEFINED, mavlink.MAV_LANDED_STATE_ON_GROUND
            ),
            "battery": mavlink.MAVLink_battery_status_message(
                0,
                mavlink.MAV_BATTERY_FUNCTION_ALL,
                mavlink.MAV_BATTERY_TYPE_LIPO,
                _INT16_MAX,
                [_UINT16_MAX] * 10,
                0,
                0,
                0,
                100,
            ),
            "home": mavlink.MAVLink_home_position_message(
                lat, lon, alt, 0.0, 0.0, 0.0, [1.0, 0.0, 0.0, 0.0], 0.0, 0.0, 0.0, 0
            ),
            "gps": mavlink.MAVLink_gps_raw_int_message(
                0, 0, lat, lon, alt, 121, 200, 0, 0, 0
            ),
            "system_time": mavlink.MAVLink_system_time_message(0, 0),
        }

    def _heartbeat(self):
        ap = self.autopilot
        msg = self._prebuilt["heartbeat"]
        msg.base_mode = ap.base_mode
        msg.custom_mode = ap.custom_mode
        if ap.crashed:
            msg.system_status = mavlink.MAV_STATE_EMERGENCY
        elif ap.armed:
            msg.system_status = mavlink.MAV_STATE_ACTIVE
        else:
            msg.system_status = mavlink.MAV_STATE_STANDBY
        return msg

    def _time_ms(self) -> int:
        return int(self.time * 1000.0) & 0xFFFFFFFF

    def _attitude(self):
        m = self.autopilot.model
        msg = self._prebuilt["attitude"]
        msg.time_boot_ms = self._time_ms()
        msg.roll, msg.pitch = m.attitude()
        msg.yaw = m.heading
        msg.yawspeed = m.yaw_speed
        return msg

    def _global_position_int(self):
        ap = self.autopilot
        m = ap.model
        msg = self._prebuilt["gpi"]
        lat, lon = self.to_global(m.x, m.y)
        rel = m.z - ap.home_z
        msg.time_boot_ms = self._time_ms()
        msg.lat = int(round(lat * 1e7))
        msg.lon = int(round(lon * 1e7))
        msg.alt = int(round((self.settings.home.alt + rel) * 1000.0))
        msg.relative_alt = int(round(rel * 1000.0))
        msg.vx = int(round(m.vy * 100.0))
        msg.vy = int(round(m.vx * 100.0))
        msg.vz = int(round(-m.vz * 100.0))
        msg.hdg = int(round(math.degrees(m.heading) * 100.0)) % 36000
        return msg

    def _local_position_ned(self):
        ap = self.autopilot
        m = ap.model
        msg = self._prebuilt["lpn"]
        msg.time_boot_ms = self._time_ms()
        msg.x, msg.y, msg.z = m.y, m.x, -(m.z - ap.home_z)
        msg.vx, msg.vy, msg.vz = m.vy, m.vx, -m.vz
        return msg

    def _distance_sensor(self):
        m = self.autopilot.model
        s = self.settings
        msg = self._prebuilt["distance"]
        roll, pitch = m.attitude()
        tilt = max(math.cos(roll) * math.cos(pitch), 0.1)
        distance = self.agl() / tilt
        # Beyond the sensor's range it reports max + 1 cm, as ArduPilot does for "out of range".
        cm = min(max(distance, s.rangefinder_min), s.rangefinder_max + 0.01) * 100.0
        msg.time_boot_ms = self._time_ms()
        msg.current_distance = int(round(cm))
        return msg

    def _sys_status(self):
        ap = self.autopilot
        b = ap.battery
        msg = self._prebuilt["sys_status"]
        health = _SENSORS if ap.settled else _SENSORS & ~_NEEDS_SETTLING
        msg.onboard_control_sensors_health = health
        msg.load = 200
        msg.voltage_battery = int(b.voltage * 1000.0)
        msg.current_battery = int(b.current * 100.0)
        msg.battery_remaining = int(b.percent)
        return msg

    def _extended_sys_state(self):
        msg = self._prebuilt["ess"]
        msg.landed_state = self.autopilot.landed_state
        return msg

    def _battery_status(self):
        b = self.autopilot.battery
        msg = self._prebuilt["battery"]
        mv = int(b.voltage * 1000.0)
        msg.voltages = [min(mv, _UINT16_MAX - 1)] + [_UINT16_MAX] * 9
        msg.current_battery = int(b.current * 100.0)
        msg.current_consumed = int(b.consumed_mah)
        msg.energy_consumed = int(b.energy_j / 100.0)
        msg.battery_remaining = int(b.percent)
        return msg

    def _home_position(self):
        msg = self._prebuilt["home"]
        msg.time_usec = int(self.time * 1e6)
        return msg

    def _gps_raw_int(self):
        ap = self.autopilot
        m = ap.model
        msg = self._prebuilt["gps"]
        lat, lon = self.to_global(m.x, m.y)
        msg.time_usec = int(self.time * 1e6)
        msg.fix_type = mavlink.GPS_FIX_TYPE_3D_FIX if ap.settled else mavlink.GPS_FIX_TYPE_NO_FIX
        msg.satellites_visible = 12 if ap.settled else 3
        msg.lat = int(round(lat * 1e7))
        msg.lon = int(round(lon * 1e7))
        msg.alt = int(round((self.settings.home.alt + m.z - ap.home_z) * 1000.0))
        speed = math.hypot(m.vx, m.vy)
        msg.vel = int(speed * 100.0)
        course = math.degrees(math.atan2(m.vx, m.vy)) % 360.0 if speed > 0.1 else 0.0
        msg.cog = int(course * 100.0) % 36000
        return msg

    def _system_time(self):
        msg = self._prebuilt["system_time"]
        msg.time_unix_usec = int((self.settings.unix_time_at_boot + self.time) * 1e6)
        msg.time_boot_ms = self._time_ms()
        return msg

    def _autopilot_version(self):
        return mavlink.MAVLink_autopilot_version_message(
            _CAPABILITIES, 0x040500FF, 0, 0, 0, [0] * 8, [0] * 8, [0] * 8, 0, 0, 0
        )
