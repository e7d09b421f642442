"""pymavlink's MAVLink codec with its common case done in fewer steps, byte for byte the same.

A lockstep flight packs and parses some forty telemetry packets per simulated second, and
pymavlink spends most of its time there on bookkeeping around the wire format (a header
object and a CRC object per packet, a Struct per header, a list per payload). For unsigned
MAVLink 2 packets of messages without array fields, :class:`FastMAVLink` packs and decodes
with one precomputed Struct per message type and the compiled CRC pymavlink itself uses
(fastcrc). Everything else (MAVLink 1, signing, arrays, unknown ids, bad CRCs, a client's
callbacks) goes through pymavlink unchanged, so the bytes on the wire, the decoded messages
and the errors are the ones pymavlink gives (tests/sitl/test_codec.py compares them).

Only what pymavlink does to the :class:`MAVLink` object itself is kept on send (sequence
number, counters, callback); the sent message object is not annotated with its packed form
(``_msgbuf``, ``_header``), which nothing here reads back.
"""

from __future__ import annotations

import struct
from operator import attrgetter, itemgetter
from typing import Any

from pymavlink.dialects.v20 import ardupilotmega as mavlink

try:  # what pymavlink's own x25crc uses when importable (a dependency of pymavlink)
    from fastcrc.crc16 import mcrf4xx as _crc16
except ImportError:  # pragma: no cover - pymavlink requires fastcrc
    _crc16 = None

_V1 = mavlink.PROTOCOL_MARKER_V1
_V2 = mavlink.PROTOCOL_MARKER_V2
_SIGNED = mavlink.MAVLINK_IFLAG_SIGNED
_SIGNATURE = mavlink.MAVLINK_SIGNATURE_BLOCK_LEN
_CORE = struct.Struct("<BBBBBBHB")  # a MAVLink 2 header after its magic byte
_MAGIC_V2 = bytes((_V2,))
_CRC = struct.Struct("<H")
_MAVError = mavlink.MAVError
_BadData = mavlink.MAVLink_bad_data
_Header = mavlink.MAVLink_header
_new = mavlink.MAVLink_message.__new__


class _Plan:
    """How one message type is packed and decoded on the fast path."""

    __slots__ = ("unpacker", "size", "extra", "get", "orders", "names", "strings", "template",
                 "msgid", "cls", "direct", "arrays", "fields", "pick", "record", "flat",
                 "gather", "spread", "msgid_low", "msgid_high", "to_wire", "quick")

    def __init__(self, cls: type) -> None:
        self.unpacker = cls.unpacker
        self.size = cls.unpacker.size
        self.extra = bytes((cls.crc_extra,))
        self.msgid = cls.id
        self.msgid_low, self.msgid_high = cls.id & 0xFFFF, cls.id >> 16
        self.cls = cls
        self.get = attrgetter(*cls.ordered_fieldnames)
        self.orders = tuple(cls.orders)
        self.names = tuple(cls.fieldnames)
        lengths = list(cls.lengths)  # struct values per wire-order field
        items = _items(cls.unpacker.format)
        if len(items) != sum(lengths):
            raise ValueError(f"{cls.msgname}: its Struct does not match its fields")
        # Wire-order (offset, count) of each declared field, as pymavlink's decode reads them:
        # count 0 is one value, else a list of that many (a char array is one bytes value).
        self.fields = []
        for order in self.orders:
            tip = sum(lengths[:order])
            count = lengths[order]
            scalar = count == 1 or items[tip] in "cs"
            self.fields.append((tip, 0 if scalar else count))
        self.fields = tuple(self.fields)
        # Without arrays, the declared fields are single values picked from the wire tuple;
        # else a function made for the type gathers them (lists for the arrays).
        self.pick = None
        if all(count == 0 for _, count in self.fields) and len(self.fields) > 1:
            self.pick = itemgetter(*(tip for tip, _ in self.fields))
        self.gather = _function("w", "[" + ", ".join(
            f"w[{tip}]" if not count else f"list(w[{tip}:{tip + count}])"
            for tip, count in self.fields) + "]")
        self.arrays = tuple(length if length > 1 and items[sum(lengths[:j])] not in "cs" else 0
                            for j, length in enumerate(lengths))  # wire order, for packing
        if not any(self.arrays):
            self.arrays = ()
        # The Struct's values from the wire-order fields, arrays spread out; None when an
        # array is shorter than its type says.
        self.spread = None
        if self.arrays:
            short = " or ".join(f"len(v[{j}]) < {n}" for j, n in enumerate(self.arrays) if n)
            spread = ", ".join(f"v[{j}]" if not n else ", ".join(f"v[{j}][{k}]" for k in range(n))
                               for j, n in enumerate(self.arrays))
            self.spread = _function("v", f"None if {short} else ({spread},)")
        # Several fields and no arrays: ``get`` alone gives the values to pack.
        self.flat = not self.arrays and len(self.orders) > 1
        # The declared fields' values in wire order (for such a type).
        self.to_wire = (itemgetter(*(self.orders.index(j) for j in range(len(self.orders))))
                        if self.flat else None)
        # pymavlink strips trailing NULs off every bytes value: chars ('c') and strings ('Ns').
        self.strings = tuple(i for i, (tip, count) in enumerate(self.fields)
                             if count == 0 and items[tip] in "cs")
        # Attributes every decoded message of this type gets besides its fields, when its
        # constructor only stores its arguments (some convert them: then it is called).
        samples = [object() for _ in self.names]
        try:
            proto = cls(*samples)
            stored = (getattr(proto, n) for n in self.names)
            self.direct = all(a is b for a, b in zip(stored, samples, strict=True))
        except Exception:  # noqa: BLE001 - a constructor that works on its values
            self.direct = False
        self.template = {}
        if self.direct:
            self.template = {k: v for k, v in vars(proto).items()
                             if k not in self.names and k not in (
                                 "_header", "_payload", "_msgbuf", "_crc", "_signed")}
        self.record = _record_type(cls.msgname, self.names) if self.direct else None
        # What read_records needs of a type read as a record with its fields picked from the
        # wire tuple (no arrays, no strings), in one attribute.
        self.quick = None
        if self.record is not None and self.pick is not None and not self.strings:
            self.quick = (self.size, self.unpacker.unpack_from, self.unpacker.unpack, self.pick,
                          self.record)

    def decoded(self, msgbuf: bytes | bytearray) -> tuple | list:
        """The declared fields' values of the whole MAVLink 2 packet ``msgbuf`` (header to
        CRC), as pymavlink's decode makes them."""
        if len(msgbuf) - 12 >= self.size:
            wire = self.unpacker.unpack_from(msgbuf, 10)
        else:  # MAVLink 2 cut the payload's trailing zeros: put them back
            wire = self.unpacker.unpack(msgbuf[10:-2].ljust(self.size, b"\x00"))
        values = self.pick(wire) if self.pick is not None else self.gather(wire)
        if self.strings:
            values = list(values)
            for index in self.strings:
                values[index] = values[index].rstrip(b"\x00")
        return values

    def values(self, msg: Any) -> tuple | None:
        """The Struct's values of ``msg`` in wire order, or None when an array field is not
        as long as its type says (pymavlink's pack then raises its own error)."""
        values = self.get(msg)
        if not isinstance(values, tuple):
            values = (values,)
        if not self.arrays:
            return values
        return self.spread(values)


def _function(arg: str, expression: str) -> Any:
    """``lambda arg: expression``, compiled once per message type (as namedtuple makes its
    methods): a plan's indexing spelled out runs faster than a loop over the plan."""
    return eval(f"lambda {arg}: {expression}", {})  # noqa: S307 - indices made here, no input


class MessageRecord(tuple):
    """A decoded message as a tuple: its fields in pymavlink's declaration order, then the
    sender's system and component ids and the packet. Each message type has a subclass whose
    fields read by name as on pymavlink's message (``record.yaw``), with the few methods of
    pymavlink's a reader of fields uses; built by :meth:`FastMAVLink.read_record`."""

    __slots__ = ()
    _type = ""

    def get_type(self) -> str:
        return self._type

    def get_srcSystem(self) -> int:  # noqa: N802 - pymavlink's name
        return self[-3]

    def get_srcComponent(self) -> int:  # noqa: N802 - pymavlink's name
        return self[-2]

    def get_msgbuf(self) -> bytes:
        return self[-1]


def _record_type(msgname: str, names: tuple[str, ...]) -> type[MessageRecord]:
    space: dict[str, Any] = {name: property(itemgetter(i)) for i, name in enumerate(names)}
    space.update(__slots__=(), _type=msgname)
    return type(f"{msgname}_record", (MessageRecord,), space)


def _items(fmt: str) -> str:
    """One struct code per value a format packs ("<I2f5s" -> "Iffs")."""
    out, count = [], ""
    for ch in fmt.lstrip("<>=!@"):
        if ch.isdigit():
            count += ch
            continue
        out.append(ch if ch == "s" else ch * int(count or 1))
        count = ""
    return "".join(out)


def _plans() -> dict[int, _Plan]:
    plans = {}
    for msgid, cls in mavlink.mavlink_map.items():
        try:
            plans[msgid] = _Plan(cls)
        except ValueError:  # pymavlink's own code handles it
            continue
    return plans


_PLANS: dict[int, _Plan] = _plans() if _crc16 is not None else {}
# Packing reads the fields as stored: only for types whose constructor stores its arguments
# (the others convert them, and their own pack() converts them back).
_BY_CLASS: dict[type, _Plan] = {p.cls: p for p in _PLANS.values() if p.direct}
_IGNORE_CRC = bool(mavlink.MAVLINK_IGNORE_CRC)


class FastMAVLink(mavlink.MAVLink):
    """:class:`pymavlink.dialects.v20.ardupilotmega.MAVLink` with faster ``send``,
    ``parse_char`` and ``decode`` for unsigned MAVLink 2 packets (see the module docstring);
    a drop-in replacement."""

    def send(self, mavmsg: Any, force_mavlink1: bool = False) -> None:
        plan = _BY_CLASS.get(type(mavmsg))
        if plan is None or force_mavlink1 or self.signing.sign_outgoing:
            super().send(mavmsg, force_mavlink1=force_mavlink1)
            return
        if plan.flat:  # the attributes in wire order are the Struct's values
            payload = plan.unpacker.pack(*plan.get(mavmsg))
        else:
            values = plan.values(mavmsg)
            if values is None:
                super().send(mavmsg, force_mavlink1=force_mavlink1)
                return
            payload = plan.unpacker.pack(*values)
        self._frame(plan, payload)
        if (self.send_callback is not None and self.send_callback_args is not None
                and self.send_callback_kwargs is not None):
            self.send_callback(mavmsg, *self.send_callback_args, **self.send_callback_kwargs)

    def send_values(self, msgid: int, values: tuple) -> None:
        """Send a message of type ``msgid`` given the values its Struct packs (wire order,
        arrays spread): the bytes :meth:`send` makes of that message, without building it.
        For a sender that signs nothing and has no send callback (the SITL's links; check
        :attr:`sends_values`)."""
        plan = _PLANS[msgid]
        self._frame(plan, plan.unpacker.pack(*values))

    def send_fields(self, msgid: int, fields: tuple) -> None:
        """Send a message of type ``msgid`` given its fields in declaration order (the
        arguments of its pymavlink constructor): the bytes :meth:`send` makes of
        ``mavlink_map[msgid](*fields)``, without building it when the type has no arrays, its
        constructor only stores its arguments and :attr:`sends_values` holds (else built and
        sent by :meth:`send`)."""
        plan = _PLANS.get(msgid)
        if (plan is None or plan.to_wire is None or not plan.direct
                or not self.sends_values):  # pymavlink's way
            self.send(mavlink.mavlink_map[msgid](*fields))
            return
        self._frame(plan, plan.unpacker.pack(*plan.to_wire(fields)))

    @property
    def sends_values(self) -> bool:
        """Whether :meth:`send_values` may be used: nothing signed, no send callback."""
        return not self.signing.sign_outgoing and self.send_callback is None

    def _frame(self, plan: _Plan, payload: bytes) -> None:
        """Write ``payload`` (the Struct's packing) as an unsigned MAVLink 2 packet."""
        # MAVLink 2 drops trailing zero bytes of the payload (at least one byte stays).
        payload = payload.rstrip(b"\x00") or b"\x00"
        seq = self.seq
        # The header after the magic byte, the payload: what the CRC covers (then crc_extra).
        core = _CORE.pack(len(payload), 0, 0, seq, self.srcSystem, self.srcComponent,
                          plan.msgid_low, plan.msgid_high) + payload
        buf = _MAGIC_V2 + core + _CRC.pack(_crc16(plan.extra, _crc16(core, 0xFFFF)))
        self.file.write(buf)
        self.seq = (seq + 1) % 256
        self.total_packets_sent += 1
        self.total_bytes_sent += len(buf)

    def parse_char(self, c: Any) -> Any:
        if not self.robust_parsing:
            return super().parse_char(c)
        self.buf.extend(c)
        self.total_bytes_received += len(c)
        m = self._parse_robust()
        if m is not None:
            self.total_packets_received += 1
            if (self.callback is not None and self.callback_args is not None
                    and self.callback_kwargs is not None):
                self.callback(m, *self.callback_args, **self.callback_kwargs)
        if self.buf_index != 0 and len(self.buf) == self.buf_index:
            self.buf = bytearray()
            self.buf_index = 0
        return m

    def _parse_robust(self) -> Any:
        """pymavlink's framing with robust parsing (``__parse_char_legacy``), step for step."""
        buf = self.buf
        i = self.buf_index
        available = len(buf) - i
        header_len = mavlink.HEADER_LEN_V1
        magic = incompat = 0
        if available >= 1:
            first = buf[i]
            if first == _V2:
                header_len = mavlink.HEADER_LEN_V2
            elif first != _V1:
                start = i
                i += 1
                end = len(buf)
                while i < end and buf[i] != _V1 and buf[i] != _V2:
                    i += 1
                self.buf_index = i
                self.expected_length = header_len + 2
                self.total_receive_errors += 1
                return _BadData(buf[start:i], "Bad prefix")
        self.have_prefix_error = False
        if available >= 3:
            magic, length, incompat = buf[i], buf[i + 1], buf[i + 2]
            if magic == _V2 and incompat & _SIGNED:
                length += _SIGNATURE
            self.expected_length = length + header_len + 2
        expected = self.expected_length
        if expected < header_len + 2 or available < expected:
            return None
        packet = buf[i : i + expected]
        self.buf_index = i + expected
        self.expected_length = header_len + 2
        try:
            if magic == _V2 and (incompat & ~_SIGNED) != 0:
                raise _MAVError(f"invalid incompat_flags 0x{incompat:x} 0x{magic:x} "
                                f"{self.expected_length}")
            return self.decode(packet)
        except _MAVError as reason:
            self.total_receive_errors += 1
            return _BadData(packet, reason.message)

    def read_record(self, buf: bytes | bytearray, pos: int) -> tuple[Any, int] | None:
        """The packet starting at ``buf[pos]`` and the index after it, when it is a whole
        unsigned MAVLink 2 packet with a good CRC of a type packed here and no signing key is
        set: a :class:`MessageRecord` (a pymavlink message for the few types whose
        constructor converts its values). Otherwise None: those bytes are ``parse_char``'s,
        which says what pymavlink makes of them (a message, bad data, or wait for more).

        A reader that only reads fields takes a clean packet here in one step instead of
        through the parse buffer and a message object; from a packet boundary with
        ``parse_char``'s buffer empty, both read the same packet. The parser's counters
        (``total_packets_received``, ...) do not count the packets read here."""
        records, stop = self.read_records(buf, pos, 1)
        return (records[0], stop) if records else None

    def read_records(self, buf: bytes | bytearray, pos: int = 0,
                     limit: int = -1) -> tuple[list, int]:
        """:meth:`read_record` repeated from ``buf[pos]`` for as long as the packets are
        clean, at most ``limit`` of them (negative: no limit): the messages read and the
        index after the last one (``pos`` when the first is not clean). One call per batch
        of a link's arrivals instead of one per packet."""
        out: list = []
        end = len(buf)
        if end - pos < 12 or self.signing.secret_key is not None or _IGNORE_CRC:
            return out, pos
        if type(buf) is not bytes:  # one copy here, none per packet
            buf, end, base = bytes(buf[pos:]), end - pos, pos
            pos = 0
        else:
            base = 0
        plans, crc16, count = _PLANS, _crc16, 0
        while count != limit and end - pos >= 12 and buf[pos] == _V2 and buf[pos + 2] == 0:
            stop = pos + buf[pos + 1] + 12
            if stop > end:
                break
            plan = plans.get(buf[pos + 7] | buf[pos + 8] << 8 | buf[pos + 9] << 16)
            if plan is None:
                break
            packet = buf[pos:stop]
            if crc16(plan.extra, crc16(packet[1:-2], 0xFFFF)) != packet[-2] | packet[-1] << 8:
                break
            quick = plan.quick
            if quick is not None:  # decoded(), inline
                size, unpack_from, unpack, pick, record = quick
                if stop - pos - 12 >= size:
                    values = pick(unpack_from(packet, 10))
                else:  # trailing zeros cut: put them back
                    values = pick(unpack(packet[10:-2].ljust(size, b"\x00")))
                out.append(record((*values, packet[5], packet[6], packet)))
            elif plan.record is None:
                out.append(self.decode(bytearray(packet)))
            else:
                out.append(plan.record((*plan.decoded(packet), packet[5], packet[6], packet)))
            pos = stop
            count += 1
        return out, base + pos

    def parse_records(self, data: bytes) -> list:
        """The messages of ``data`` as ``parse_buffer`` gives them (but a list, maybe
        empty), clean packets as records (:meth:`read_records`) while the parser holds
        nothing; from the first packet that is not clean, pymavlink's parser reads the
        rest."""
        out, pos = [], 0
        if self.buf_index == len(self.buf):
            out, pos = self.read_records(data)
        if pos < len(data):
            out.extend(self.parse_buffer(data[pos:]) or ())
        return out

    def decode(self, msgbuf: bytearray) -> Any:
        if (msgbuf[0] != _V2 or msgbuf[2] != 0 or self.signing.secret_key is not None
                or _IGNORE_CRC or len(msgbuf) != msgbuf[1] + 12):
            return super().decode(msgbuf)
        msgid = msgbuf[7] | msgbuf[8] << 8 | msgbuf[9] << 16
        plan = _PLANS.get(msgid)
        if plan is None:
            return super().decode(msgbuf)
        crc = msgbuf[-2] | msgbuf[-1] << 8
        if _crc16(plan.extra, _crc16(memoryview(msgbuf)[1:-2], 0xFFFF)) != crc:
            return super().decode(msgbuf)  # raises pymavlink's own error
        values = plan.decoded(msgbuf)
        if plan.direct:
            m = _new(plan.cls)
            fields = dict(zip(plan.names, values, strict=True))
            fields.update(plan.template)
            m.__dict__ = fields
        else:
            m = plan.cls(*values)
            fields = vars(m)
        fields["_signed"] = False
        fields["_msgbuf"] = msgbuf
        fields["_payload"] = msgbuf[6:-2]  # sic: pymavlink's offset, kept for equality
        fields["_crc"] = crc
        fields["_header"] = _Header(msgid, 0, msgbuf[3], msgbuf[1], msgbuf[4], msgbuf[5],
                                    msgbuf[6])
        return m


__all__ = ["FastMAVLink", "MessageRecord"]
