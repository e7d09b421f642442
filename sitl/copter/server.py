"""The SITL's MAVLink side: links, message handling and the telemetry scheduler.

A :class:`MavlinkServer` serves any number of links (anything with ``read() -> bytes`` and
``write(bytes)``). Per link it keeps a pymavlink parser, a sequence counter and its own message
intervals, as ArduPilot keeps them per channel. Incoming bytes are parsed with pymavlink's
robust parser (corrupt bytes are skipped and counted); outgoing messages are packed by
pymavlink into one buffer per link and written once per step.

No message may stop the simulator: each handler reads its fields defensively, and should one
still raise, the message is dropped and counted (``handler_errors``) instead of the exception
escaping, so a ground station's odd message costs that message and nothing else.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import ftp
from .autopilot import UNSUPPORTED, Autopilot
from .codec import FastMAVLink
from .commands import CommandRequest, Commands
from .kinematics import Setpoint
from .mission_protocol import MissionProtocol, Upload
from .param_protocol import ParamProtocol
from .telemetry import STREAMS, Telemetry

# Legacy REQUEST_DATA_STREAM groups (MAVProxy and older GCSs still use them).
_DATA_STREAMS: dict[int, tuple[int, ...]] = {
    mavlink.MAV_DATA_STREAM_EXTENDED_STATUS: (
        mavlink.MAVLINK_MSG_ID_SYS_STATUS,
        mavlink.MAVLINK_MSG_ID_GPS_RAW_INT,
        mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE,
        mavlink.MAVLINK_MSG_ID_MISSION_CURRENT,
        mavlink.MAVLINK_MSG_ID_FENCE_STATUS,  # ArduPilot's, while a fence is enabled
    ),
    mavlink.MAV_DATA_STREAM_POSITION: (
        mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT,
        mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED,
    ),
    mavlink.MAV_DATA_STREAM_EXTRA1: (mavlink.MAVLINK_MSG_ID_ATTITUDE,),
    mavlink.MAV_DATA_STREAM_EXTRA2: (mavlink.MAVLINK_MSG_ID_VFR_HUD,),  # the HUD
    mavlink.MAV_DATA_STREAM_EXTRA3: (
        mavlink.MAVLINK_MSG_ID_BATTERY_STATUS,
        mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR,
        mavlink.MAVLINK_MSG_ID_SYSTEM_TIME,
        mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT,
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
# SET_POSITION_TARGET_LOCAL_NED frames: positions relative to the vehicle, axes turned with
# its heading (ArduPilot's handling of the body and offset frames).
_OFFSET_FRAMES = frozenset({
    mavlink.MAV_FRAME_LOCAL_OFFSET_NED, mavlink.MAV_FRAME_BODY_NED,
    mavlink.MAV_FRAME_BODY_OFFSET_NED,
})
_BODY_FRAMES = frozenset({mavlink.MAV_FRAME_BODY_NED, mavlink.MAV_FRAME_BODY_OFFSET_NED})
_LOCAL_FRAMES = _OFFSET_FRAMES | {mavlink.MAV_FRAME_LOCAL_NED}
_RADIO_STATUS = mavlink.MAVLINK_MSG_ID_RADIO_STATUS
_MAVLINK_EPOCH = 1420070400.0  # 2015-01-01, origin of MAVLink signing timestamps


class _Outbox:
    """File-like sink for pymavlink: collects the packets of one step."""

    __slots__ = ("chunks", "write")

    def __init__(self) -> None:
        self.chunks: list[bytes] = []
        self.write = self.chunks.append  # write(data): no Python frame per packet


class Link:
    """One MAVLink peer: its endpoint, parser, sequence counter, stream intervals and the
    parameter list or mission upload in progress on it."""

    def __init__(self, endpoint, system_id: int, component_id: int) -> None:
        self.endpoint = endpoint
        self.outbox = _Outbox()
        self.mav = FastMAVLink(self.outbox, srcSystem=system_id, srcComponent=component_id)
        self.mav.robust_parsing = True
        self.open = False  # we talk on it (a packet arrived, or it greets, e.g. TCP)
        self.intervals: dict[int, float] = {}  # msgid -> seconds
        self.next_due: dict[int, float] = {}
        self.once: list[int] = []
        self.home_sent = False
        self.param_queue: list[int] = []
        self.upload: Upload | None = None
        self.packets_received = 0
        self.corrupt_packets = 0
        self.corrupt_bytes = 0

    @property
    def closed(self) -> bool:
        return bool(getattr(self.endpoint, "closed", False))

    @property
    def refused_unsigned(self) -> int:
        """Packets refused for a missing or bad signature (while signing is on)."""
        return self.mav.signing.reject_count

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
        signing_key: a 32-byte MAVLink 2 signing key in force from boot (None: unsigned until
            a SETUP_SIGNING message sets one).
    """

    def __init__(
        self,
        autopilot: Autopilot,
        agl: Callable[[], float],
        *,
        streams_by_default: bool,
        signing_key: bytes | None = None,
    ) -> None:
        self.autopilot = autopilot
        self.agl = agl
        self.streams_by_default = streams_by_default
        self.links: list[Link] = []
        self.time = 0.0
        rates = autopilot.settings.rates
        self.default_intervals = {
            msgid: 1.0 / getattr(rates, name)
            for msgid, name in STREAMS.items()
            if getattr(rates, name) > 0
        }
        self.ignored_setpoints = 0
        self.handler_errors = 0  # messages whose handler raised (a bug; see the docstring)
        self.foreign_messages = 0  # addressed to another system or component
        self.signing_key: bytes | None = None
        self.telemetry = Telemetry(self)
        self.commands = Commands(self)
        self.params = ParamProtocol(self)
        self.missions = MissionProtocol(self)
        self._handlers: dict[str, Callable[[Link, object], None]] = {
            "COMMAND_LONG": self._on_command_long,
            "COMMAND_INT": self._on_command_int,
            "SET_MODE": self._on_set_mode,
            "SET_POSITION_TARGET_LOCAL_NED": self._on_position_target_local,
            "SET_POSITION_TARGET_GLOBAL_INT": self._on_position_target_global,
            "REQUEST_DATA_STREAM": self._on_request_data_stream,
            "SETUP_SIGNING": self._on_setup_signing,
            "TIMESYNC": self._on_timesync,
            "FILE_TRANSFER_PROTOCOL": self._on_file_transfer,
            "AUTOPILOT_VERSION_REQUEST": self._on_autopilot_version_request,
            **self.params.handlers,
            **self.missions.handlers,
        }
        self._cache: dict[int, object] = {}
        self._mission_now = (autopilot.mission.current, autopilot.auto.mission_state)
        if signing_key is not None:
            self._sign_with(signing_key, 0)

    @property
    def settings(self):
        return self.autopilot.settings

    # ------------------------------------------------------------------ links
    def attach(self, endpoint) -> Link:
        """Serve ``endpoint``. One that ``greets`` (a TCP client, a UDP port with a fixed
        peer) is talked to at once, as the real autopilots greet such links."""
        s = self.settings
        link = Link(endpoint, s.system_id, s.component_id)
        if self.signing_key is not None:
            self._sign_link(link, self._signing_timestamp())
        self.links.append(link)
        if self.streams_by_default or getattr(endpoint, "greets", False):
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

    def can_stream(self, msgid: int) -> bool:
        return msgid in STREAMS and msgid in self.telemetry.builders

    def can_build(self, msgid: int) -> bool:
        return msgid in self.telemetry.builders

    def can_send(self, msgid: int) -> bool:
        """Whether ``msgid`` requested now would go out: HOME_POSITION waits for a position
        estimate, FENCE_STATUS for an enabled fence (emit() sends neither before)."""
        if msgid == mavlink.MAVLINK_MSG_ID_HOME_POSITION:
            return self.autopilot.position_known
        build = self.telemetry.builders.get(msgid)
        if msgid == mavlink.MAVLINK_MSG_ID_FENCE_STATUS and build is not None:
            return build() is not None
        return build is not None

    # ---------------------------------------------------------------- receive
    def receive(self) -> None:
        """Read and handle everything that arrived on every link."""
        for link in self.links:
            if link.closed:  # rare: rebuild the list only then
                self.links = [link for link in self.links if not link.closed]
                break
        for link in self.links:
            data = link.endpoint.read()
            if not data:
                continue
            for msg in link.mav.parse_records(data):
                name = msg.get_type()
                if name == "BAD_DATA":
                    link.corrupt_packets += 1
                    link.corrupt_bytes += len(msg.data)
                    continue
                link.packets_received += 1
                if not link.open:
                    self._open(link)
                handler = self._handlers.get(name)
                if handler is None:
                    continue
                if not self._for_me(msg):
                    self.foreign_messages += 1
                    continue
                try:
                    handler(link, msg)
                except Exception:  # noqa: BLE001 - see the module docstring
                    self.handler_errors += 1

    def _for_me(self, msg) -> bool:
        s = self.settings
        system = getattr(msg, "target_system", 0)
        component = getattr(msg, "target_component", 0)
        return system in (0, s.system_id) and component in (0, s.component_id)

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

    def _ack(self, link: Link, command: int, result: int, msg) -> None:
        # The ACK goes out first and the STATUSTEXT saying why in the same step after it, the
        # order ArduPilot sends them in (its texts wait in a queue of their own).
        link.mav.send(mavlink.MAVLink_command_ack_message(
            command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()
        ))
        self._send_texts()

    def _on_command_long(self, link: Link, msg) -> None:
        params = (
            msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7
        )
        request = CommandRequest(msg.command, params)
        self._ack(link, msg.command, self.commands.handle(link, request), msg)

    def _on_command_int(self, link: Link, msg) -> None:
        params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
        request = CommandRequest(msg.command, params, frame=msg.frame)
        self._ack(link, msg.command, self.commands.handle(link, request), msg)

    def set_mode_number(self, custom_mode: int) -> int:
        """Switch to the personality's mode numbered ``custom_mode``; the MAV_RESULT."""
        ap = self.autopilot
        name = ap.mode_name(custom_mode)
        return ap.set_mode(name if name is not None else f"mode {custom_mode}")

    def _on_set_mode(self, link: Link, msg) -> None:
        if not msg.base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            result = UNSUPPORTED
        else:
            result = self.set_mode_number(msg.custom_mode)
        # ArduPilot ACKs SET_MODE with the message id (11) as the command.
        self._ack(link, mavlink.MAVLINK_MSG_ID_SET_MODE, result, msg)

    # ---------------------------------------------------------------- targets
    def global_to_enu(
        self, lat: float | None, lon: float | None, alt: float | None, frame: int
    ) -> tuple[float, float, float] | None:
        """A global point (None keeps the vehicle's own coordinate) in ENU metres, or None."""
        ap = self.autopilot
        return ap.geo.to_enu(lat, lon, alt, frame, ap.model.position)

    def _on_position_target_local(self, link: Link, msg) -> None:
        m = self.autopilot.model
        frame = msg.coordinate_frame
        if frame not in _LOCAL_FRAMES:
            self.ignored_setpoints += 1
            return
        position = velocity = None
        mask = msg.type_mask
        if frame in _BODY_FRAMES:
            # Body axes: x forward, y right, turned by the heading (clockwise from north).
            c, s = math.cos(m.heading), math.sin(m.heading)

            def turn(x: float, y: float) -> tuple[float, float]:
                return x * c - y * s, x * s + y * c
        else:

            def turn(x: float, y: float) -> tuple[float, float]:
                return x, y

        if not mask & _IGNORE_POSITION:
            north, east = turn(msg.x, msg.y)
            if frame in _OFFSET_FRAMES:
                position = (m.x + east, m.y + north, m.z - msg.z)
            else:
                # In the EKF's frame: it drifts from the truth while GPS is lost.
                ap = self.autopilot
                position = ap.estimate_to_truth((east, north, ap.origin_z - msg.z))
        if not mask & _IGNORE_VELOCITY:
            vn, ve = turn(msg.vx, msg.vy)
            velocity = (ve, vn, -msg.vz)
        self._target(msg, position, velocity)

    def _on_position_target_global(self, link: Link, msg) -> None:
        position = velocity = None
        mask = msg.type_mask
        if not mask & _IGNORE_POSITION:
            position = self.global_to_enu(
                msg.lat_int * 1e-7, msg.lon_int * 1e-7, msg.alt, msg.coordinate_frame
            )
            if position is None:
                self.ignored_setpoints += 1
                return
            position = self.autopilot.estimate_to_truth(position)
        if not mask & _IGNORE_VELOCITY:
            velocity = (msg.vy, msg.vx, -msg.vz)
        self._target(msg, position, velocity)

    def _target(self, msg, position, velocity) -> None:
        """Hand a decoded position target (ENU) to the autopilot, if it is usable."""
        ap = self.autopilot
        values = (*(position or ()), *(velocity or ()))
        if not all(math.isfinite(v) for v in values):
            self.ignored_setpoints += 1
            return
        mask = msg.type_mask
        yaw = None if mask & _IGNORE_YAW or not math.isfinite(msg.yaw) else msg.yaw
        yaw_rate = None
        if not mask & _IGNORE_YAW_RATE and math.isfinite(msg.yaw_rate):
            yaw_rate = msg.yaw_rate
        if position is None and velocity is None:
            if yaw is None and yaw_rate is None:
                self.ignored_setpoints += 1
                return
            position = ap.model.position  # a yaw-only target holds position
        ap.position_target(
            Setpoint(position=position, velocity=velocity, yaw=yaw, yaw_rate=yaw_rate)
        )

    def _on_request_data_stream(self, link: Link, msg) -> None:
        group = _DATA_STREAMS.get(msg.req_stream_id, ())
        rate = msg.req_message_rate if msg.start_stop else 0
        for msgid in group:
            if self.can_stream(msgid):
                link.set_interval(msgid, 1.0 / rate if rate > 0 else 0.0, self.time)

    # ---------------------------------------------------------------- signing, time
    def _signing_timestamp(self) -> int:
        """Now in MAVLink signing units (10 us since 2015-01-01), from the SITL's clock."""
        unix = self.settings.unix_time_at_boot + self.time
        return max(0, int((unix - _MAVLINK_EPOCH) * 1e5))

    def _sign_link(self, link: Link, timestamp: int) -> None:
        signing = link.mav.signing
        signing.secret_key = self.signing_key
        signing.sign_outgoing = True
        signing.link_id = 0
        signing.timestamp = max(signing.timestamp, timestamp)
        # ArduPilot takes RADIO_STATUS unsigned (radios cannot sign); nothing else.
        signing.allow_unsigned_callback = lambda mav, msg_id: msg_id == _RADIO_STATUS

    def _sign_with(self, key: bytes, initial_timestamp: int) -> None:
        self.signing_key = key
        timestamp = max(initial_timestamp, self._signing_timestamp())
        for link in self.links:
            self._sign_link(link, timestamp)

    def _on_setup_signing(self, link: Link, msg) -> None:
        """SETUP_SIGNING: a key of zeros turns signing off, any other turns it on for every
        link (unsigned packets are then refused and counted), as ArduPilot does."""
        key = bytes(msg.secret_key)
        if len(key) != 32:
            return
        if not any(key):
            self.signing_key = None
            for each in self.links:
                signing = each.mav.signing
                signing.secret_key = None
                signing.sign_outgoing = False
                signing.allow_unsigned_callback = None
            return
        self._sign_with(key, int(msg.initial_timestamp))

    def _on_timesync(self, link: Link, msg) -> None:
        """TIMESYNC with tc1 = 0 is a request: answer with our time in tc1, theirs in ts1."""
        if msg.tc1 == 0:
            link.mav.send(mavlink.MAVLink_timesync_message(int(self.time * 1e9), msg.ts1))

    def _on_autopilot_version_request(self, link: Link, msg) -> None:
        """ArduPilot's own older request (a message, so no ACK): answered while its
        AP_MAVLINK_AUTOPILOT_VERSION_REQUEST_ENABLED stays on, by default
        (GCS_MAVLINK::handle_send_autopilot_version). PX4 has no handler for it."""
        if self.autopilot.name == "ardupilot":
            link.once.append(mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)

    def _on_file_transfer(self, link: Link, msg) -> None:
        answer = ftp.reply(msg)
        if answer is not None:
            link.mav.send(answer)

    # ------------------------------------------------------------------- emit
    def send_mission_current(self) -> None:
        """MISSION_CURRENT to every open link (the current item changed)."""
        msg = self.telemetry.mission_current()
        for link in self.links:
            if link.open:
                link.mav.send(msg)

    def _mission_events(self) -> None:
        ap = self.autopilot
        reached = ap.auto.reached
        for seq in reached:
            msg = mavlink.MAVLink_mission_item_reached_message(seq)
            for link in self.links:
                if link.open:
                    link.mav.send(msg)
        reached.clear()
        now = (ap.mission.current, ap.auto.mission_state)
        if now != self._mission_now:
            self._mission_now = now
            if ap.announces_mission_current:
                self.send_mission_current()

    def send_named_value_int(self, name: str, value: int, now: float) -> None:
        """NAMED_VALUE_INT ``name`` = ``value`` at sim time ``now`` to every open link (a
        companion's sensor)."""
        ms = int(now * 1000.0) & 0xFFFFFFFF
        msg = mavlink.MAVLink_named_value_int_message(ms, name.encode(), int(value))
        for link in self.links:
            if link.open:
                link.mav.send(msg)

    def emit(self, now: float) -> None:
        """Send the STATUSTEXTs and every telemetry message due at ``now``; flush links."""
        self.time = now
        ap = self.autopilot
        if ap.texts:
            self._send_texts()
        if ap.auto.reached or (ap.mission.current, ap.auto.mission_state) != self._mission_now:
            self._mission_events()
        cache = self._cache
        cache.clear()
        home_msg = mavlink.MAVLINK_MSG_ID_HOME_POSITION
        build = self.telemetry.builders
        values = self.telemetry.values
        known = ap.position_known  # asked once: it only changes with the time
        for link in self.links:
            if not link.open:
                continue
            if known and (not link.home_sent or ap.home_changed):
                link.once.append(home_msg)
            mav = link.mav
            once = link.once
            for msgid in once:
                if msgid == home_msg:
                    if not known:
                        continue  # no home until the EKF has a position
                    link.home_sent = True
                msg = build[msgid]()
                if msg is not None:  # (FENCE_STATUS without a fence)
                    mav.send(msg)
            once.clear()
            due = link.next_due
            limit = now + 1e-9
            direct = mav.sends_values
            for msgid, when in due.items():
                if limit >= when:
                    if msgid == home_msg and not known:
                        continue
                    if direct and msgid in values:  # packed from its values, no message
                        key = -msgid
                        fields = cache.get(key)
                        if fields is None:
                            fields = cache[key] = values[msgid]()
                        mav.send_values(msgid, fields)
                    else:
                        msg = cache.get(msgid)
                        if msg is None:
                            msg = cache[msgid] = build[msgid]()
                        if msg is not None:  # (FENCE_STATUS without a fence: nothing)
                            mav.send(msg)
                    interval = link.intervals[msgid]
                    nxt = when + interval
                    due[msgid] = nxt if nxt > now else now + interval
            if link.param_queue:  # a parameter list being sent
                self.params.emit(link)
            if link.upload is not None:  # a mission upload in progress
                self.missions.emit(link)
            link.flush()
        if known:
            ap.home_changed = False
