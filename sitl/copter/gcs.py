"""A minimal lockstep ground station for the SITL: tests, benchmarks and examples.

Not a vehicle driver (that is the autonomy's job): it only sends raw MAVLink commands through
pymavlink and keeps what came back, so a test can say "arm" and look at the COMMAND_ACK.
"""

from __future__ import annotations

from collections import defaultdict

from pymavlink.dialects.v20 import ardupilotmega as mavlink


class _Writer:
    __slots__ = ("endpoint",)

    def __init__(self, endpoint) -> None:
        self.endpoint = endpoint

    def write(self, data: bytes) -> None:
        self.endpoint.write(data)


class MiniGcs:
    """A pymavlink client on ``endpoint`` (e.g. :attr:`sitl.link.MemoryLink.gcs`).

    ``poll()`` parses what arrived; ``received`` keeps every message in order, ``last`` the
    newest of each type, ``counts`` how many of each type arrived.
    """

    def __init__(self, endpoint, system_id: int = 255, component_id: int = 190,
                 target_system: int = 1, target_component: int = 1) -> None:
        self.endpoint = endpoint
        self.mav = mavlink.MAVLink(_Writer(endpoint), system_id, component_id)
        self.mav.robust_parsing = True
        self.target = (target_system, target_component)
        self.received: list = []
        self.last: dict[str, object] = {}
        self.counts: dict[str, int] = defaultdict(int)
        self.keep = True
        self.upload: list = []  # MISSION_ITEM_INT messages offered to the vehicle's requests
        self.downloaded: list = []  # items received since the last download_mission()
        self._download: tuple[int, int] | None = None  # (count, mission_type) in progress

    def poll(self) -> list:
        """Parse everything that arrived; returns the new messages. Answers the vehicle's
        requests for the items of :meth:`upload_mission` and asks for the next item of a
        :meth:`download_mission`."""
        data = self.endpoint.read()
        if not data:
            return []
        msgs = self.mav.parse_buffer(data) or []
        for msg in msgs:
            name = msg.get_type()
            self.last[name] = msg
            self.counts[name] += 1
            if name in ("MISSION_REQUEST_INT", "MISSION_REQUEST") and msg.seq < len(self.upload):
                self.mav.send(self.upload[msg.seq])
            elif name in ("MISSION_COUNT", "MISSION_ITEM_INT") and self._download is not None:
                self._next_download(msg)
        if self.keep:
            self.received.extend(msgs)
        return msgs

    def of_type(self, name: str) -> list:
        return [m for m in self.received if m.get_type() == name]

    def texts(self) -> list[str]:
        return [m.text for m in self.of_type("STATUSTEXT")]

    def acks(self, command: int) -> list[int]:
        """Results of the COMMAND_ACKs received for ``command``, in order."""
        return [m.result for m in self.of_type("COMMAND_ACK") if m.command == command]

    # ----------------------------------------------------------------- sending
    def heartbeat(self) -> None:
        self.mav.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)

    def command(self, command: int, *params: float) -> None:
        p = list(params) + [0.0] * (7 - len(params))
        self.mav.command_long_send(*self.target, command, 0, *p)

    def set_interval(self, msgid: int, hz: float) -> None:
        """SET_MESSAGE_INTERVAL: ``hz`` > 0 streams, 0 = default rate, < 0 stops."""
        interval = 1e6 / hz if hz > 0 else (0 if hz == 0 else -1)
        self.command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, msgid, interval)

    def arm(self, force: bool = False) -> None:
        self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1, 2989 if force else 0)

    def disarm(self, force: bool = False) -> None:
        self.command(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196 if force else 0)

    def set_mode(self, custom_mode: int, px4: bool = False) -> None:
        """MAV_CMD_DO_SET_MODE; for PX4 ``custom_mode`` is the HEARTBEAT encoding."""
        flag = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if px4:
            main, sub = (custom_mode >> 16) & 0xFF, (custom_mode >> 24) & 0xFF
            self.command(mavlink.MAV_CMD_DO_SET_MODE, flag, main, sub)
        else:
            self.command(mavlink.MAV_CMD_DO_SET_MODE, flag, custom_mode)

    def takeoff(self, altitude: float) -> None:
        self.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, float("nan"), 0, 0, altitude)

    def land(self) -> None:
        self.command(mavlink.MAV_CMD_NAV_LAND, 0, 0, 0, float("nan"), 0, 0, 0)

    def goto_ned(self, north: float, east: float, down: float) -> None:
        """SET_POSITION_TARGET_LOCAL_NED, position only (MAV_FRAME_LOCAL_NED)."""
        mask = 0b0000_1101_1111_1000  # use x, y, z; ignore velocity, accel, yaw, yaw rate
        self.mav.set_position_target_local_ned_send(
            0, *self.target, mavlink.MAV_FRAME_LOCAL_NED, mask,
            north, east, down, 0, 0, 0, 0, 0, 0, 0, 0,
        )

    def velocity_ned(self, vn: float, ve: float, vd: float) -> None:
        """SET_POSITION_TARGET_LOCAL_NED, velocity only (MAV_FRAME_LOCAL_NED)."""
        mask = 0b0000_1101_1100_0111  # use vx, vy, vz
        self.mav.set_position_target_local_ned_send(
            0, *self.target, mavlink.MAV_FRAME_LOCAL_NED, mask,
            0, 0, 0, vn, ve, vd, 0, 0, 0, 0, 0,
        )

    # ----------------------------------------------------------------- parameters
    def param_request_list(self) -> None:
        self.mav.param_request_list_send(*self.target)

    def param_read(self, name: str = "", index: int = -1) -> None:
        self.mav.param_request_read_send(*self.target, name.encode(), index)

    def param_set(self, name: str, value: float, param_type: int) -> None:
        self.mav.param_set_send(*self.target, name.encode(), value, param_type)

    def params(self) -> dict[str, float]:
        """The newest PARAM_VALUE of each parameter received, by name."""
        return {m.param_id: m.param_value for m in self.of_type("PARAM_VALUE")}

    # ----------------------------------------------------------------- missions
    def mission_item(self, seq: int, command: int, lat: float = 0.0, lon: float = 0.0,
                     alt: float = 0.0, *, frame: int = mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                     params: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0),
                     mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION):
        """A MISSION_ITEM_INT for :meth:`upload_mission` (lat/lon in degrees)."""
        return mavlink.MAVLink_mission_item_int_message(
            *self.target, seq, frame, command, 0, 1, *params,
            int(round(lat * 1e7)), int(round(lon * 1e7)), alt, mission_type,
        )

    def upload_mission(self, items: list,
                       mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION) -> None:
        """Start an upload; :meth:`poll` sends each item the vehicle asks for. The vehicle's
        MISSION_ACK ends it."""
        self.upload = list(items)
        self.mav.mission_count_send(*self.target, len(items), mission_type)

    def download_mission(self, mission_type: int = mavlink.MAV_MISSION_TYPE_MISSION) -> None:
        """Start a download; the items arrive in :attr:`downloaded` as :meth:`poll` runs."""
        self.downloaded = []
        self._download = (-1, mission_type)
        self.mav.mission_request_list_send(*self.target, mission_type)

    def _next_download(self, msg) -> None:
        count, mission_type = self._download
        if msg.get_type() == "MISSION_COUNT":
            count = msg.count
        else:
            self.downloaded.append(msg)
        self._download = (count, mission_type)
        if len(self.downloaded) < count:
            self.mav.mission_request_int_send(*self.target, len(self.downloaded), mission_type)
        else:
            self._download = None
            self.mav.mission_ack_send(*self.target, mavlink.MAV_MISSION_ACCEPTED, mission_type)
