"""COMMAND_LONG and COMMAND_INT: what the simulated autopilot does with each MAV_CMD.

Ground stations and SDKs fill the parameters they do not use with NaN (MAVLink allows it, and
for many commands NaN means "keep the current value"), and anything may arrive in a field, so
every parameter is read through :class:`CommandRequest`, which turns NaN, infinities and
out-of-range numbers into None instead of raising. Each handler returns the MAV_RESULT the
real autopilot would give; a command nobody handles gets MAV_RESULT_UNSUPPORTED.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from . import protocol_version
from .autopilot import ACCEPTED, DENIED, FAILED, UNSUPPORTED
from .personalities import FORCE_ARM, FORCE_DISARM

if TYPE_CHECKING:
    from .server import Link, MavlinkServer

_INT32_MAX = 2**31 - 1
# COMMAND_LONG carries positions in MAV_FRAME_GLOBAL (altitude above mean sea level).
_LONG_FRAME = mavlink.MAV_FRAME_GLOBAL
_REPOSITION_CHANGE_MODE = mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE
_FAR_FROM_ORIGIN = 50_000.0  # m: ArduPilot's EKF_ORIGIN_MAX_DIST_M, the farthest home it sets


@dataclass(frozen=True, slots=True)
class CommandRequest:
    """One COMMAND_LONG or COMMAND_INT, its seven parameters as sent.

    For COMMAND_INT, ``params[4]`` and ``params[5]`` are the integer ``x`` and ``y``
    (degrees * 1e7 in a global frame) and ``frame`` is the message's frame; for COMMAND_LONG
    ``frame`` is None.
    """

    command: int
    params: tuple[float, float, float, float, float, float, float]
    frame: int | None = None

    def value(self, index: int) -> float | None:
        """Parameter ``index`` (1..7) as a finite float, or None (NaN, inf: "not given")."""
        v = self.params[index - 1]
        return float(v) if math.isfinite(v) else None

    def integer(self, index: int, default: int | None = None) -> int | None:
        """Parameter ``index`` (1..7) as an int when it is a finite whole number in int32
        range, else ``default``."""
        v = self.value(index)
        if v is None or abs(v) > _INT32_MAX or v != int(v):
            return default
        return int(v)

    def location(self) -> tuple[float | None, float | None, float | None, int]:
        """(lat deg, lon deg, alt m, frame) of params 5-7; None where not given. COMMAND_INT
        marks "not given" with INT32_MAX in x and y; COMMAND_LONG with NaN."""
        if self.frame is None:
            lat, lon = self.value(5), self.value(6)
            frame = _LONG_FRAME
        else:
            x, y = self.params[4], self.params[5]
            lat = None if x == _INT32_MAX else x * 1e-7
            lon = None if y == _INT32_MAX else y * 1e-7
            frame = self.frame
        if lat is not None and not -90.0 <= lat <= 90.0:
            lat = None
        if lon is not None and not -180.0 <= lon <= 180.0:
            lon = None
        return lat, lon, self.value(7), frame


Handler = Callable[["Link", CommandRequest], int]


class Commands:
    """The MAV_CMD handlers of one :class:`~sitl.copter.server.MavlinkServer`."""

    def __init__(self, server: MavlinkServer) -> None:
        self.server = server
        self.autopilot = server.autopilot
        c = mavlink
        self.handlers: dict[int, Handler] = {
            c.MAV_CMD_SET_MESSAGE_INTERVAL: self._set_message_interval,
            c.MAV_CMD_GET_MESSAGE_INTERVAL: self._get_message_interval,
            c.MAV_CMD_REQUEST_MESSAGE: self._request_message,
            c.MAV_CMD_GET_HOME_POSITION: self._get_home_position,
            c.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES: self._request_capabilities,
            c.MAV_CMD_REQUEST_PROTOCOL_VERSION: self._request_protocol_version,
            c.MAV_CMD_COMPONENT_ARM_DISARM: self._arm_disarm,
            c.MAV_CMD_NAV_TAKEOFF: self._takeoff,
            c.MAV_CMD_NAV_LAND: self._land,
            c.MAV_CMD_NAV_RETURN_TO_LAUNCH: self._return_to_launch,
            c.MAV_CMD_DO_SET_MODE: self._do_set_mode,
            c.MAV_CMD_DO_REPOSITION: self._do_reposition,
            c.MAV_CMD_DO_CHANGE_SPEED: self._do_change_speed,
            c.MAV_CMD_MISSION_START: self._mission_start,
            c.MAV_CMD_DO_LAND_START: self._do_land_start,
            c.MAV_CMD_DO_SET_MISSION_CURRENT: self._set_mission_current,
            c.MAV_CMD_CONDITION_YAW: self._condition_yaw,
            c.MAV_CMD_DO_FLIGHTTERMINATION: self._flight_termination,
            c.MAV_CMD_DO_SET_HOME: self._do_set_home,
            c.MAV_CMD_DO_FENCE_ENABLE: lambda link, r: self.autopilot.fence.enable(r.integer(1)),
        }

    def handle(self, link: Link, request: CommandRequest) -> int:
        handler = self.handlers.get(request.command)
        if handler is None:
            return UNSUPPORTED
        return handler(link, request)

    # ------------------------------------------------------------------ telemetry
    def _set_message_interval(self, link: Link, r: CommandRequest) -> int:
        msgid = r.integer(1)
        us = r.value(2)
        if msgid is None or us is None:
            return DENIED
        server = self.server
        if us == 0:
            interval = server.default_intervals.get(msgid, 0.0)
        elif us < 0:
            interval = 0.0
        else:
            interval = us * 1e-6
        if not server.can_stream(msgid):
            return self._cannot_send(msgid, stream=True)
        link.set_interval(msgid, interval, server.time)
        return ACCEPTED

    def _get_message_interval(self, link: Link, r: CommandRequest) -> int:
        msgid = r.integer(1)
        if msgid is None or not 0 <= msgid <= 0xFFFF:
            return DENIED
        interval = link.intervals.get(msgid)
        if interval:
            us = min(int(interval * 1e6), _INT32_MAX)
        else:
            us = -1 if self.server.can_stream(msgid) else 0
        link.mav.send(mavlink.MAVLink_message_interval_message(msgid, us))
        return ACCEPTED

    def _cannot_send(self, msgid: int | None, stream: bool) -> int:
        """The answer to a request for a message this vehicle does not send. ArduPilot fails
        both kinds (an interval with "No ap_message for mavlink id (N)"); PX4 fails an
        interval and denies a single message (MavlinkReceiver)."""
        if self.autopilot.name == "px4":
            return FAILED if stream else DENIED
        if stream:
            text = f"No ap_message for mavlink id ({msgid})"
            self.autopilot.text(mavlink.MAV_SEVERITY_INFO, text)
        return FAILED

    def _request_message(self, link: Link, r: CommandRequest) -> int:
        msgid = r.integer(1)
        if (self.autopilot.name == "ardupilot" and msgid is not None
                and self.server.can_build(msgid) and not self.server.can_send(msgid)):
            # ArduPilot queues a message it knows and ACCEPTs, whether or not it has one to
            # send (handle_command_request_message; send_home_position sends nothing before
            # home is set, FENCE_STATUS nothing without a fence): a client must not take
            # ACCEPTED as the message's promise, and this simulator does not teach it to.
            return ACCEPTED
        return self._send_once(link, msgid)

    def _send_once(self, link: Link, msgid: int | None) -> int:
        """Send ``msgid`` once, or refuse it. PX4 denies what it cannot send now
        (MavlinkReceiver::handle_request_message_command: the stream's request_message()
        sent nothing). ArduPilot fails an unknown message (handle_command_request_message)
        and GET_HOME_POSITION before home is set (handle_command_get_home_position)."""
        if msgid is None or not self.server.can_send(msgid):
            return self._cannot_send(msgid, stream=False)
        link.once.append(msgid)
        return ACCEPTED

    def _get_home_position(self, link: Link, r: CommandRequest) -> int:
        """No home before the position estimate: FAILED on ArduPilot, DENIED on PX4 (which
        answers it as a request for HOME_POSITION)."""
        return self._send_once(link, mavlink.MAVLINK_MSG_ID_HOME_POSITION)

    def _request_capabilities(self, link: Link, r: CommandRequest) -> int:
        """AUTOPILOT_VERSION. ArduPilot fails it unless param1 is 1
        (handle_command_request_autopilot_capabilities); PX4 answers any."""
        if self.autopilot.name == "ardupilot" and r.value(1) != 1.0:
            return FAILED
        return self._send_once(link, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)

    def _request_protocol_version(self, link: Link, r: CommandRequest) -> int:
        """PX4 answers it as a request for PROTOCOL_VERSION (MavlinkReceiver); ArduPilot has
        no handler for it (GCS_MAVLINK::handle_command_int_packet: unsupported)."""
        if self.autopilot.name != "px4":
            return UNSUPPORTED
        return self._send_once(link, protocol_version.MSG_ID)

    # ------------------------------------------------------------------ flight
    def _arm_disarm(self, link: Link, r: CommandRequest) -> int:
        ap = self.autopilot
        arm = r.value(1)
        magic = r.integer(2, 0)
        if arm == 1.0:
            return ap.arm(force=magic == FORCE_ARM)
        if arm == 0.0:
            return ap.disarm(force=magic == FORCE_DISARM)
        return DENIED

    def _flight_termination(self, link: Link, r: CommandRequest) -> int:
        """MAVSDK's terminate(): param1 > 0.5 stops the motors, in the air too."""
        value = r.value(1)
        return self.autopilot.terminate(value is not None and value > 0.5)

    def _takeoff(self, link: Link, r: CommandRequest) -> int:
        return self.autopilot.takeoff(r.params[6] if r.value(7) is not None else math.nan)

    def _land(self, link: Link, r: CommandRequest) -> int:
        return self.autopilot.land()

    def _return_to_launch(self, link: Link, r: CommandRequest) -> int:
        return self.autopilot.return_to_launch()

    def _do_set_mode(self, link: Link, r: CommandRequest) -> int:
        """ArduPilot's custom mode is param2; PX4's main and sub modes are param2 and 3."""
        base_mode = r.integer(1)
        main = r.integer(2)
        if base_mode is None or main is None or main < 0:
            return DENIED
        if not base_mode & mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
            return UNSUPPORTED
        if self.autopilot.name == "px4":
            sub = r.integer(3, 0)
            if not 0 <= main <= 0xFF or sub is None or not 0 <= sub <= 0xFF:
                return DENIED
            custom = (main << 16) | (sub << 24)
        else:
            custom = main
        return self.server.set_mode_number(custom)

    def _do_reposition(self, link: Link, r: CommandRequest) -> int:
        """Fly to a global point: param1 ground speed (m/s, < 0 or NaN: unchanged), param2
        MAV_DO_REPOSITION_FLAGS, param4 yaw (rad, NaN: unchanged), params 5-7 the point."""
        lat, lon, alt, frame = r.location()
        target = self.server.global_to_enu(lat, lon, alt, frame)
        if target is None:
            return DENIED
        flags = r.integer(2, 0)
        speed = r.value(1)
        yaw = r.value(4)
        return self.autopilot.reposition(
            target,
            change_mode=bool(flags & _REPOSITION_CHANGE_MODE),
            speed=speed if speed is not None and speed > 0 else None,
            yaw=yaw,
        )

    def _do_set_home(self, link: Link, r: CommandRequest) -> int:
        """param1 1: home here; else params 5-7 the new home (COMMAND_LONG: lat, lon, alt
        AMSL). Home is then locked: arming keeps it (ArduPilot locks home set by
        handle_command_do_set_home; PX4 marks it manual_home)."""
        ap = self.autopilot
        if not ap.position_known:
            return FAILED  # no EKF origin yet: ArduPilot's set_home fails, PX4 has no home
        if r.value(1) == 1.0:
            x, y = ap.estimated_xy()
            ap.set_home(x, y, ap.model.z, lock=True)
            return ACCEPTED
        return self.set_home_to(*r.location())

    def set_home_to(self, lat: float | None, lon: float | None, alt: float | None,
                    frame: int = _LONG_FRAME) -> int:
        """Move (and lock) home to a global point: DENIED for a latitude or longitude
        missing, NaN or out of range, or no altitude (ArduPilot's check_latlng and
        location_from_command_t; PX4 needs all three finite); FAILED on ArduPilot for a
        home more than 50 km from the EKF origin (Copter::far_from_EKF_origin)."""
        ap = self.autopilot
        if lat is None or lon is None or alt is None:
            return DENIED
        point = self.server.global_to_enu(lat, lon, alt, frame)
        if point is None:
            return DENIED
        if ap.name == "ardupilot" and math.hypot(point[0], point[1]) > _FAR_FROM_ORIGIN:
            return FAILED
        ap.set_home(*point, lock=True)
        return ACCEPTED

    def _do_change_speed(self, link: Link, r: CommandRequest) -> int:
        """param1 speed type (0 air, 1 ground, 2 climb, 3 descent), param2 m/s (-1: unchanged)."""
        return self.autopilot.speed_command(r.integer(1, 1), r.value(2))

    def _mission_start(self, link: Link, r: CommandRequest) -> int:
        """param1 the first item, param2 the last (0: all). ArduPilot Copter flies the whole
        mission only and denies anything else (handle_MAV_CMD_MISSION_START)."""
        if self.autopilot.name == "ardupilot" and not (r.params[0] == 0 and r.params[1] == 0):
            return DENIED
        first = r.integer(1, 0)
        return self.autopilot.mission_start(first or None)

    def _do_land_start(self, link: Link, r: CommandRequest) -> int:
        """MAV_CMD_DO_LAND_START (MAVProxy's `land`): fly the mission's landing sequence, from
        its DO_LAND_START item, in the mission mode; FAILED when it has none (ArduPilot)."""
        store = self.autopilot.mission
        items = store.items
        for seq in range(store.first, len(items)):
            if items[seq].command == mavlink.MAV_CMD_DO_LAND_START:
                return self.autopilot.mission_start(seq)
        return FAILED

    def _set_mission_current(self, link: Link, r: CommandRequest) -> int:
        seq = r.integer(1)
        if seq is None or not self.autopilot.set_mission_current(seq):
            return DENIED
        return ACCEPTED

    def _condition_yaw(self, link: Link, r: CommandRequest) -> int:
        """param1 heading or change (deg), param3 direction (-1 ccw, 1 cw), param4 relative."""
        angle = r.value(1)
        if angle is None:
            return DENIED
        relative = r.integer(4, 0) == 1
        direction = -1.0 if r.value(3) == -1.0 else 1.0
        return self.autopilot.point_yaw(math.radians(angle), relative, direction)


__all__ = ["CommandRequest", "Commands"]
