"""MAVLink's parameter protocol on the SITL's links.

PARAM_REQUEST_LIST queues every parameter on the asking link, sent a batch per step (the
real autopilots stream them rather than flood the link); PARAM_REQUEST_READ answers one by
name or index; PARAM_SET sets and answers on every link with the value now in force (the old
one when the set was refused). Unknown names get no answer, as on ArduPilot and PX4.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .params import ParameterTable, param_id

if TYPE_CHECKING:
    from .server import Link, MavlinkServer

_BATCH = 32  # PARAM_VALUEs one link gets per step while a list is being sent


def _name(raw) -> str:
    """PARAM_*.param_id as text (pymavlink gives str; bad bytes are replaced)."""
    if isinstance(raw, (bytes, bytearray)):
        raw = raw.decode("ascii", "replace")
    return str(raw).split("\x00", 1)[0]


class ParamProtocol:
    """Answers the parameter messages for one server's autopilot."""

    def __init__(self, server: MavlinkServer) -> None:
        self.server = server
        self.table: ParameterTable = server.autopilot.params
        self.handlers = {
            "PARAM_REQUEST_LIST": self._request_list,
            "PARAM_REQUEST_READ": self._request_read,
            "PARAM_SET": self._set,
        }

    def _message(self, index: int):
        table = self.table
        return mavlink.MAVLink_param_value_message(
            param_id(table.rows[index].name).encode("ascii"),
            table.encode(index),
            table.rows[index].type,
            len(table),
            index,
        )

    def _request_list(self, link: Link, msg) -> None:
        link.param_queue = list(range(len(self.table)))

    def _request_read(self, link: Link, msg) -> None:
        index = msg.param_index
        if index < 0:
            index = self.table.find(_name(msg.param_id))
        elif index >= len(self.table):
            index = None
        if index is not None:
            link.mav.send(self._message(index))

    def _set(self, link: Link, msg) -> None:
        index = self.table.find(_name(msg.param_id))
        if index is None:
            return
        value = self.table.decode(msg.param_value, msg.param_type)
        self.table.set(index, value)
        reply = self._message(index)
        for other in self.server.links:
            if other.open:
                other.mav.send(reply)

    def emit(self, link: Link) -> None:
        """Send the next batch of a requested list on ``link``."""
        queue = link.param_queue
        if not queue:
            return
        for index in queue[:_BATCH]:
            link.mav.send(self._message(index))
        del queue[:_BATCH]
