"""MAVLink's mission protocol on the SITL's links: upload, download, clear, current item.

Upload: MISSION_COUNT starts it; the vehicle asks for each item with MISSION_REQUEST_INT
(again after ``_RETRY`` s of silence, up to ``_ATTEMPTS`` times), takes MISSION_ITEM_INT or
MISSION_ITEM, and ends with MISSION_ACK. Download: MISSION_REQUEST_LIST gets MISSION_COUNT,
each MISSION_REQUEST_INT (or MISSION_REQUEST) the item. Fence and rally plans are stored the
same way (and not enforced: the simulator has no geofence). ArduPilot's guided "fly to" item
(MISSION_ITEM with current = 2) is answered here too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .mission import MISSION, TYPES, MissionItem, problem

if TYPE_CHECKING:
    from .server import Link, MavlinkServer

_RETRY = 1.0  # s without the requested item before asking again
_ATTEMPTS = 8  # requests for one item before the upload is abandoned
_GUIDED_GOTO = 2  # MISSION_ITEM.current: ArduPilot's guided "fly to"
_GUIDED_ALTITUDE = 3  # MISSION_ITEM.current: ArduPilot's guided altitude change
_FLOAT_TWIN = {
    mavlink.MAV_FRAME_GLOBAL_INT: mavlink.MAV_FRAME_GLOBAL,
    mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT,
    mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT: mavlink.MAV_FRAME_GLOBAL_TERRAIN_ALT,
}

ACCEPTED = mavlink.MAV_MISSION_ACCEPTED
ERROR = mavlink.MAV_MISSION_ERROR


@dataclass
class Upload:
    """An upload in progress on one link."""

    mission_type: int
    count: int
    peer: tuple[int, int]
    items: list[MissionItem] = field(default_factory=list)
    asked_at: float = 0.0
    attempts: int = 0


class MissionProtocol:
    """Answers the mission messages for one server's autopilot."""

    def __init__(self, server: MavlinkServer) -> None:
        self.server = server
        self.autopilot = server.autopilot
        self.store = server.autopilot.mission
        self.uploads_abandoned = 0
        self.handlers = {
            "MISSION_COUNT": self._count,
            "MISSION_ITEM": self._item,
            "MISSION_ITEM_INT": self._item,
            "MISSION_REQUEST_LIST": self._request_list,
            "MISSION_REQUEST": self._request,
            "MISSION_REQUEST_INT": self._request,
            "MISSION_CLEAR_ALL": self._clear_all,
            "MISSION_SET_CURRENT": self._set_current,
            "MISSION_WRITE_PARTIAL_LIST": self._partial,
            "MISSION_ACK": self._ack_from_peer,
        }

    # ------------------------------------------------------------------ replies
    def _ack(self, link: Link, peer: tuple[int, int], result: int, mission_type: int) -> None:
        link.mav.send(mavlink.MAVLink_mission_ack_message(peer[0], peer[1], result, mission_type))

    def _ask(self, link: Link, upload: Upload) -> None:
        upload.asked_at = self.server.time
        upload.attempts += 1
        link.mav.send(mavlink.MAVLink_mission_request_int_message(
            upload.peer[0], upload.peer[1], len(upload.items), upload.mission_type
        ))

    @staticmethod
    def _peer(msg) -> tuple[int, int]:
        return msg.get_srcSystem(), msg.get_srcComponent()

    @staticmethod
    def _type(msg) -> int | None:
        mission_type = getattr(msg, "mission_type", MISSION)
        return mission_type if mission_type in TYPES else None

    # ------------------------------------------------------------------ upload
    def _count(self, link: Link, msg) -> None:
        peer = self._peer(msg)
        mission_type = self._type(msg)
        if mission_type is None:
            self._ack(link, peer, mavlink.MAV_MISSION_UNSUPPORTED, msg.mission_type)
            return
        if msg.count > self.store.capacity:
            self._ack(link, peer, mavlink.MAV_MISSION_NO_SPACE, mission_type)
            return
        if msg.count == 0:
            link.upload = None
            self.store.replace(mission_type, [])
            self._ack(link, peer, ACCEPTED, mission_type)
            return
        link.upload = Upload(mission_type, msg.count, peer)
        self._ask(link, link.upload)

    def _item(self, link: Link, msg) -> None:
        upload = link.upload
        if upload is None:
            self._outside_upload(link, msg)
            return
        if self._type(msg) != upload.mission_type:
            return
        if msg.seq != len(upload.items):
            self._ask(link, upload)  # a repeat or a skip: ask for the one we need
            return
        item = MissionItem.from_message(msg)
        refused = problem(item)
        if refused is not None:
            link.upload = None
            self._ack(link, upload.peer, refused, upload.mission_type)
            return
        upload.items.append(item)
        upload.attempts = 0
        if len(upload.items) < upload.count:
            self._ask(link, upload)
            return
        link.upload = None
        self.store.replace(upload.mission_type, upload.items)
        self._ack(link, upload.peer, ACCEPTED, upload.mission_type)

    def _outside_upload(self, link: Link, msg) -> None:
        """A MISSION_ITEM with no upload running: ArduPilot's guided target, else an error."""
        peer = self._peer(msg)
        mission_type = self._type(msg)
        if mission_type != MISSION or msg.current not in (_GUIDED_GOTO, _GUIDED_ALTITUDE):
            self._ack(link, peer, ERROR, msg.mission_type)
            return
        item = MissionItem.from_message(msg)
        ap = self.autopilot
        m = ap.model
        if msg.current == _GUIDED_ALTITUDE:
            lat = lon = None
        else:
            lat, lon = (item.x, item.y) if item.is_global else (math.nan, math.nan)
        target = ap.geo.to_enu(lat, lon, item.z, item.frame, m.position)
        if target is None or not ap.guided_goto(target):
            self._ack(link, peer, ERROR, MISSION)
            return
        self._ack(link, peer, ACCEPTED, MISSION)

    def _partial(self, link: Link, msg) -> None:
        self._ack(link, self._peer(msg), mavlink.MAV_MISSION_UNSUPPORTED, msg.mission_type)

    def _ack_from_peer(self, link: Link, msg) -> None:
        """The peer ended a transfer (a download's last ACK, or an upload it cancels)."""
        if link.upload is not None and msg.type != ACCEPTED:
            link.upload = None

    # ------------------------------------------------------------------ download
    def _request_list(self, link: Link, msg) -> None:
        mission_type = self._type(msg)
        peer = self._peer(msg)
        if mission_type is None:
            self._ack(link, peer, mavlink.MAV_MISSION_UNSUPPORTED, msg.mission_type)
            return
        link.mav.send(mavlink.MAVLink_mission_count_message(
            peer[0], peer[1], self.store.count(mission_type), mission_type
        ))

    def _request(self, link: Link, msg) -> None:
        mission_type = self._type(msg)
        peer = self._peer(msg)
        if mission_type is None or not 0 <= msg.seq < self.store.count(mission_type):
            self._ack(link, peer, mavlink.MAV_MISSION_INVALID_SEQUENCE,
                      mission_type if mission_type is not None else msg.mission_type)
            return
        item = self._stored(mission_type, msg.seq)
        frame = item.frame
        if self.autopilot.float_frames_on_download:
            frame = _FLOAT_TWIN.get(frame, frame)
        current = int(mission_type == MISSION and msg.seq == self.store.current)
        args = (item.param1, item.param2, item.param3, item.param4)
        if msg.get_type() == "MISSION_REQUEST_INT":
            x, y = item.int_xy()
            reply = mavlink.MAVLink_mission_item_int_message(
                peer[0], peer[1], msg.seq, frame, item.command, current,
                item.autocontinue, *args, x, y, item.z, mission_type,
            )
        else:
            reply = mavlink.MAVLink_mission_item_message(
                peer[0], peer[1], msg.seq, frame, item.command, current,
                item.autocontinue, *args, item.x, item.y, item.z, mission_type,
            )
        link.mav.send(reply)

    def _stored(self, mission_type: int, seq: int) -> MissionItem:
        """Item ``seq``; ArduPilot's item 0 of the mission is home, whatever was uploaded."""
        if mission_type == MISSION and seq == 0 and self.store.home_at_zero:
            lat, lon, alt = self.server.autopilot.home_geo
            return MissionItem(
                command=mavlink.MAV_CMD_NAV_WAYPOINT, frame=mavlink.MAV_FRAME_GLOBAL,
                x=lat, y=lon, z=alt,
            )
        return self.store.plans[mission_type][seq]

    # ------------------------------------------------------------------ other
    def _clear_all(self, link: Link, msg) -> None:
        mission_type = getattr(msg, "mission_type", MISSION)
        if mission_type not in TYPES and mission_type != mavlink.MAV_MISSION_TYPE_ALL:
            self._ack(link, self._peer(msg), mavlink.MAV_MISSION_UNSUPPORTED, mission_type)
            return
        self.store.clear(mission_type)
        self._ack(link, self._peer(msg), ACCEPTED, mission_type)

    def _set_current(self, link: Link, msg) -> None:
        self.autopilot.set_mission_current(msg.seq)
        self.server.send_mission_current()

    def emit(self, link: Link) -> None:
        """Ask again for an item that has not come, or give the upload up."""
        upload = link.upload
        if upload is None or self.server.time - upload.asked_at < _RETRY:
            return
        if upload.attempts >= _ATTEMPTS:
            link.upload = None
            self.uploads_abandoned += 1
            self._ack(link, upload.peer, mavlink.MAV_MISSION_OPERATION_CANCELLED,
                      upload.mission_type)
            return
        self._ask(link, upload)
