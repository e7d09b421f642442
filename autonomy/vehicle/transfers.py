"""Mission-protocol uploads and downloads and parameter sets, as handles the driver follows.

:class:`MissionUpload` is the ground station's side of MAVLink's mission upload
(mavlink.io, services/mission.md "Upload a Mission to the Vehicle"): MISSION_COUNT with the
plan's ``mission_type``, then each item the vehicle asks for by ``seq`` (MISSION_REQUEST_INT,
or the older MISSION_REQUEST, answered the same way: ArduPilot's autotest
``upload_using_mission_protocol`` and pymavlink's mavwp do so too) as MISSION_ITEM_INT, until
the vehicle's MISSION_ACK of that type. What was last sent is sent again after
``timeout`` clock seconds of silence, at most ``retries`` times (the protocol's "Timeouts and
Retries": 1500 ms, 5 retries); giving up cancels the operation on the vehicle with a
MISSION_ACK MAV_MISSION_OPERATION_CANCELLED. :class:`MissionDownload` is the other way
(services/mission.md "Download a Mission from the Vehicle"), with the same retries.

:class:`ParamSet` is one PARAM_SET followed until the vehicle's PARAM_VALUE of that name
shows the value (services/parameter.md: the answer to PARAM_SET is PARAM_VALUE; re-send
when it does not come). Nothing here waits: the driver feeds messages in and calls
``update`` on every poll.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Sequence

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.vehicle.commands import Handle
from behaviors.ports import CommandStatus

MISSION_TIMEOUT = 1.5  # s; mission protocol "Timeout (default): 1500 ms"
MISSION_RETRIES = 5  # mission protocol "Retries (max): 5"

# The fields of one MISSION_ITEM_INT after seq: frame, command, current, autocontinue,
# param1..4, x, y (int), z.
ItemFields = tuple[int, int, int, int, float, float, float, float, int, int, float]


def mission_result_name(result: int) -> str:
    """MAV_MISSION_RESULT number -> its name (``MAV_MISSION_INVALID``), or the number."""
    entry = mavlink.enums["MAV_MISSION_RESULT"].get(result)
    return entry.name if entry is not None else f"MAV_MISSION_RESULT {result}"


# struct formats of the integer MAV_PARAM_TYPEs, for PX4's byte-wise encoding.
_INTEGER_FORMATS = {
    mavlink.MAV_PARAM_TYPE_UINT8: "<B", mavlink.MAV_PARAM_TYPE_INT8: "<b",
    mavlink.MAV_PARAM_TYPE_UINT16: "<H", mavlink.MAV_PARAM_TYPE_INT16: "<h",
    mavlink.MAV_PARAM_TYPE_UINT32: "<I", mavlink.MAV_PARAM_TYPE_INT32: "<i",
}


def param_value(value: float, param_type: int, bytewise: bool) -> float:
    """PARAM_VALUE.param_value as the number it stands for. PX4 puts an integer's bytes in
    the float (MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE); ArduPilot casts it (C cast,
    MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST)."""
    fmt = _INTEGER_FORMATS.get(param_type)
    if not bytewise or fmt is None:
        return float(value)
    raw = struct.pack("<f", value)
    return float(struct.unpack(fmt, raw[:struct.calcsize(fmt)])[0])


class _MissionExchange(Handle):
    """One mission-protocol transfer of ``mission_type``: what was last sent goes again
    after ``timeout`` clock seconds of silence, at most ``retries`` times; giving up cancels
    it on the vehicle (MISSION_ACK MAV_MISSION_OPERATION_CANCELLED) and ends TIMED_OUT.

    ``send(name, fields)`` puts a message on the link (the driver addresses it).
    """

    def __init__(self, name: str, created: float, mission_type: int,
                 send: Callable[[str, tuple], None], *, timeout: float, retries: int) -> None:
        super().__init__(name, created)
        self.mission_type = mission_type
        self._send = send
        self.timeout = timeout
        self.retries = retries
        self._last: tuple[str, tuple] | None = None
        self._last_sent = created
        self._resent = 0

    def _put(self, name: str, fields: tuple, now: float) -> None:
        self._last = (name, fields)
        self._last_sent = now
        self._send(name, fields)

    def _answered(self) -> None:
        """The vehicle is answering: the retry count starts again."""
        self._resent = 0
        self._set(CommandStatus.IN_PROGRESS)

    def _awaited(self) -> str:
        """What the vehicle has not sent, for the TIMED_OUT reason."""
        raise NotImplementedError

    def update(self, now: float) -> None:
        """Re-send what the vehicle has not answered, or give up."""
        if self.done or now - self._last_sent < self.timeout - 1e-6:  # float tick sums
            return
        if self._resent >= self.retries:
            self._send("MISSION_ACK", (mavlink.MAV_MISSION_OPERATION_CANCELLED,
                                       self.mission_type))
            self._set(CommandStatus.TIMED_OUT, f"no {self._awaited()} from the autopilot "
                      f"after {self.retries + 1} attempts {self.timeout:g} s apart", now)
            return
        self._resent += 1
        assert self._last is not None
        self._put(*self._last, now)

    def cancel(self, reason: str, now: float, status: CommandStatus) -> None:
        self._set(status, reason, now)


class MissionUpload(_MissionExchange):
    """The upload of one plan (``items``) of ``mission_type`` to the vehicle.

    ``send(name, fields)`` puts a message on the link: ``("MISSION_COUNT", (count,
    mission_type))``, ``("MISSION_ITEM_INT", (seq, *item, mission_type))`` or
    ``("MISSION_ACK", (result, mission_type))``.
    """

    def __init__(
        self,
        name: str,
        created: float,
        items: Sequence[ItemFields],
        mission_type: int,
        send: Callable[[str, tuple], None],
        *,
        timeout: float = MISSION_TIMEOUT,
        retries: int = MISSION_RETRIES,
    ) -> None:
        super().__init__(name, created, mission_type, send, timeout=timeout, retries=retries)
        self.items = list(items)
        self.requested: set[int] = set()  # seqs the vehicle asked for

    def start(self, now: float) -> MissionUpload:
        self._put("MISSION_COUNT", (len(self.items), self.mission_type), now)
        return self

    def on_request(self, seq: int, mission_type: int, now: float) -> None:
        """MISSION_REQUEST_INT or MISSION_REQUEST addressed to us."""
        if self.done or mission_type != self.mission_type:
            return
        if not 0 <= seq < len(self.items):
            return  # not an item of this plan: the vehicle will ask again or refuse
        self.requested.add(seq)
        self._answered()
        self._put("MISSION_ITEM_INT", (seq, *self.items[seq], self.mission_type), now)

    def on_ack(self, result: int, mission_type: int, now: float) -> None:
        """MISSION_ACK addressed to us: the vehicle's verdict on the whole plan."""
        if self.done or mission_type != self.mission_type:
            return
        if result == mavlink.MAV_MISSION_ACCEPTED:
            if len(self.requested) == len(self.items):
                self._set(CommandStatus.ACCEPTED, now=now)
            return  # an ACK of an earlier transfer, before ours asked for its items
        self._set(CommandStatus.DENIED, f"the autopilot answered MISSION_ACK "
                  f"{mission_result_name(result)}", now)

    def _awaited(self) -> str:
        if self._last and self._last[0] == "MISSION_COUNT":
            return "MISSION_REQUEST"
        return "MISSION_REQUEST or MISSION_ACK"


class MissionDownload(_MissionExchange):
    """The download of the vehicle's plan of ``mission_type`` (services/mission.md
    "Download a Mission from the Vehicle"): MISSION_REQUEST_LIST, the vehicle's
    MISSION_COUNT, then MISSION_REQUEST_INT for each item in turn, answered by
    MISSION_ITEM_INT, and our MISSION_ACK ACCEPTED once all came. ``items`` holds them
    (:data:`ItemFields`) when ACCEPTED.

    ``send(name, fields)``: ``("MISSION_REQUEST_LIST", (mission_type,))``,
    ``("MISSION_REQUEST_INT", (seq, mission_type))`` or ``("MISSION_ACK", (result,
    mission_type))``.
    """

    def __init__(self, name: str, created: float, mission_type: int,
                 send: Callable[[str, tuple], None], *, timeout: float = MISSION_TIMEOUT,
                 retries: int = MISSION_RETRIES) -> None:
        super().__init__(name, created, mission_type, send, timeout=timeout, retries=retries)
        self.count: int | None = None
        self.items: list[ItemFields] = []

    def start(self, now: float) -> MissionDownload:
        self._put("MISSION_REQUEST_LIST", (self.mission_type,), now)
        return self

    def on_count(self, count: int, mission_type: int, now: float) -> None:
        """MISSION_COUNT addressed to us."""
        if self.done or mission_type != self.mission_type or self.count is not None:
            return
        self.count = count
        self._answered()
        self._next(now)

    def on_item(self, seq: int, fields: ItemFields, mission_type: int, now: float) -> None:
        """MISSION_ITEM_INT addressed to us; an item out of turn is a repeat and ignored."""
        if self.done or mission_type != self.mission_type or seq != len(self.items):
            return
        self.items.append(fields)
        self._answered()
        self._next(now)

    def on_ack(self, result: int, mission_type: int, now: float) -> None:
        """MISSION_ACK addressed to us: during a download only a refusal (no such plan)."""
        if self.done or mission_type != self.mission_type or \
                result == mavlink.MAV_MISSION_ACCEPTED:
            return
        self._set(CommandStatus.DENIED, f"the autopilot answered MISSION_ACK "
                  f"{mission_result_name(result)}", now)

    def _next(self, now: float) -> None:
        assert self.count is not None
        if len(self.items) < self.count:
            self._put("MISSION_REQUEST_INT", (len(self.items), self.mission_type), now)
            return
        self._send("MISSION_ACK", (mavlink.MAV_MISSION_ACCEPTED, self.mission_type))
        self._set(CommandStatus.ACCEPTED, now=now)

    def _awaited(self) -> str:
        return "MISSION_COUNT" if self.count is None else "MISSION_ITEM_INT"


class _ParamExchange(Handle):
    """A parameter request sent again every ``timeout`` until its PARAM_VALUE comes,
    TIMED_OUT after ``attempts`` (what the two exchanges below share)."""

    silence = "requests"  # what went unanswered, for the TIMED_OUT reason

    def __init__(self, label: str, created: float, param: str, *, timeout: float,
                 attempts: int) -> None:
        super().__init__(label, created)
        self.param = param
        self.timeout = timeout
        self.attempts = attempts
        self.sent = 0
        self._last_sent = created

    def start(self, now: float) -> _ParamExchange:
        self._transmit(now)
        return self

    def _transmit(self, now: float) -> None:
        self.sent += 1
        self._last_sent = now
        self._put()

    def _put(self) -> None:
        raise NotImplementedError

    def update(self, now: float) -> None:
        if self.done or now - self._last_sent < self.timeout - 1e-6:
            return
        if self.sent >= self.attempts:
            self._set(CommandStatus.TIMED_OUT, f"no PARAM_VALUE for {self.param} after "
                      f"{self.sent} {self.silence}", now)
            return
        self._transmit(now)

    def cancel(self, reason: str, now: float, status: CommandStatus) -> None:
        self._set(status, reason, now)


class ParamRead(_ParamExchange):
    """PARAM_REQUEST_READ ``param``, done with the first PARAM_VALUE of that name (``value``);
    re-sent after ``timeout``, TIMED_OUT after ``attempts``."""

    def __init__(self, created: float, param: str, send: Callable[[str], None], *,
                 timeout: float, attempts: int) -> None:
        super().__init__(f"read {param}", created, param, timeout=timeout, attempts=attempts)
        self._send = send
        self.value: float | None = None

    def _put(self) -> None:
        self._send(self.param)

    def on_value(self, param: str, value: float, now: float) -> None:
        if not self.done and param == self.param:
            self.value = value
            self._set(CommandStatus.ACCEPTED, now=now)


class ParamSet(_ParamExchange):
    """PARAM_SET ``param`` = ``value`` (as ``param_type``), done when PARAM_VALUE shows it.

    ``send(param, value, param_type)`` puts the PARAM_SET on the link. A PARAM_VALUE with
    another value is answered with the PARAM_SET again (it may have been sent before ours
    arrived); after ``attempts`` the set is DENIED with the value the vehicle kept.
    """

    silence = "PARAM_SETs (unknown to the autopilot?)"

    def __init__(
        self,
        created: float,
        param: str,
        value: float,
        param_type: int,
        send: Callable[[str, float, int], None],
        *,
        timeout: float,
        attempts: int,
    ) -> None:
        super().__init__(f"set {param} {value:g}", created, param, timeout=timeout,
                         attempts=attempts)
        self.value = float(value)
        self.param_type = param_type
        self._send = send
        self.kept: float | None = None  # another value the vehicle answered with

    def _put(self) -> None:
        self._send(self.param, self.value, self.param_type)

    def on_value(self, param: str, value: float, now: float) -> None:
        if self.done or param != self.param:
            return
        # PARAM_VALUE carries a float32: compare at its precision.
        if math.isclose(value, self.value, rel_tol=1e-6, abs_tol=1e-6):
            self._set(CommandStatus.ACCEPTED, now=now)
            return
        self.kept = value
        if self.sent >= self.attempts:
            self._set(CommandStatus.DENIED, f"the autopilot kept {self.param} = {value:g} "
                      f"(asked for {self.value:g})", now)
        else:
            self._transmit(now)


