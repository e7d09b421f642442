"""The SITL's and the driver's MAVLink codec (sitl.copter.codec.FastMAVLink) is pymavlink's,
byte for byte: the same packets for every message type, the same decoded messages, and the
same bad-data verdicts on a stream of garbage, corrupted, truncated, signed and MAVLink 1
packets, with pymavlink itself as the oracle."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl.copter.codec import FastMAVLink, MessageRecord


class _Sink:
    def __init__(self) -> None:
        self.packets: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.packets.append(bytes(data))


def _value(code: str, rng: np.random.Generator):
    """A random value of a struct field code ("I", "f", "12s", "c", ...)."""
    kind = code[-1]
    if kind == "s":
        n = int(code[:-1] or 1)
        return bytes(rng.integers(32, 127, int(rng.integers(0, n + 1))).astype(np.uint8))
    if kind == "c":
        return bytes([int(rng.integers(32, 127))])
    if kind in "fd":
        if rng.random() < 0.2:
            return 0.0
        return float(np.float32(rng.normal(0, 1000)))
    size = struct.calcsize(kind)
    signed = kind.islower() and kind != "c"
    bits = 8 * size
    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
    if rng.random() < 0.3:
        return 0  # trailing zero fields are cut off the wire
    return int(rng.integers(lo, hi, endpoint=True, dtype=np.int64)) if size < 8 else int(
        rng.integers(0, 1 << 62))


def _random_message(cls, rng):
    """A message of type ``cls`` with random field values (arrays included)."""
    fmt, count, codes = cls.unpacker.format.lstrip("<"), "", []
    for ch in fmt:  # one code per Struct value: "2f5s" -> f, f, 5s
        if ch.isdigit():
            count += ch
            continue
        codes += [count + ch] if ch == "s" else [ch] * int(count or 1)
        count = ""
    wire, pos = {}, 0
    for name, length in zip(cls.ordered_fieldnames, cls.lengths, strict=True):
        values = [_value(code, rng) for code in codes[pos : pos + length]]
        pos += length
        wire[name] = values[0] if length == 1 else values
    return cls(*[wire[name] for name in cls.fieldnames])


def _plain_types():
    """Every message type whose constructor stores its arguments as they are."""
    types = []
    for cls in mavlink.mavlink_map.values():
        try:
            _random_message(cls, np.random.default_rng(0))
        except Exception:  # noqa: BLE001 - e.g. a constructor decoding a bytes field
            continue
        types.append(cls)
    return types


def _pair():
    a, b = _Sink(), _Sink()
    return (FastMAVLink(a, srcSystem=7, srcComponent=3), a,
            mavlink.MAVLink(b, srcSystem=7, srcComponent=3), b)


def _described(msg) -> tuple:
    header = msg.get_header()
    return (msg.get_type(), msg.to_dict(), bytes(msg.get_msgbuf()), msg.get_crc(),
            None if msg.get_payload() is None else bytes(msg.get_payload()), msg.get_signed(),
            (header.msgId, header.incompat_flags, header.compat_flags, header.mlen, header.seq,
             header.srcSystem, header.srcComponent) if msg.get_type() != "BAD_DATA" else None)


def test_every_message_type_packs_and_decodes_as_pymavlink_does():
    rng = np.random.default_rng(5)
    types = _plain_types()
    assert len(types) > 250  # the whole dialect, arrays included
    fast, fast_out, slow, slow_out = _pair()
    for cls in types:
        for _ in range(3):
            msg = _random_message(cls, rng)
            fast.send(msg)
            slow.send(msg)
    assert fast_out.packets == slow_out.packets
    assert (fast.seq, fast.total_packets_sent, fast.total_bytes_sent) == (
        slow.seq, slow.total_packets_sent, slow.total_bytes_sent)
    stream = b"".join(slow_out.packets)
    fast_rx, slow_rx = FastMAVLink(None), mavlink.MAVLink(None)
    fast_rx.robust_parsing = slow_rx.robust_parsing = True
    got = [_described(m) for m in fast_rx.parse_buffer(stream)]
    want = [_described(m) for m in slow_rx.parse_buffer(stream)]
    assert len(got) == 3 * len(types)
    assert got == want


def test_fields_pack_as_the_messages_do():
    """send_fields (declared fields, no message built) sends the bytes send() sends of the
    message made of them, for every type without arrays, trailing zeros included."""
    rng = np.random.default_rng(6)
    fast, fast_out, slow, slow_out = _pair()
    sent = 0
    for cls in _plain_types():
        for _ in range(3):
            msg = _random_message(cls, rng)
            fields = tuple(getattr(msg, name) for name in cls.fieldnames)
            try:
                again = cls(*fields)  # some constructors convert what they are given
            except Exception:  # noqa: BLE001 - e.g. decoding a str field again
                continue
            if [getattr(again, n) for n in cls.fieldnames] != list(fields):
                continue
            fast.send_fields(cls.id, fields)
            slow.send(msg)
            sent += 1
    assert sent > 500
    assert fast_out.packets == slow_out.packets


def _damaged_stream(rng) -> bytes:
    """Telemetry packets of every kind the parser must cope with, in random order."""
    return b"".join(_damaged_parts(rng))


def _damaged_parts(rng) -> list[bytes]:
    """The packets (and bits of garbage) of :func:`_damaged_stream`, one by one."""
    sink = _Sink()
    plain = mavlink.MAVLink(sink, srcSystem=1, srcComponent=1)
    signed = mavlink.MAVLink(sink, srcSystem=1, srcComponent=1)
    signed.signing.secret_key = bytes(range(32))
    signed.signing.sign_outgoing = True
    types = _plain_types()
    parts = []
    for _ in range(400):
        cls = types[int(rng.integers(len(types)))]
        msg = _random_message(cls, rng)
        roll = rng.random()
        if roll < 0.1:
            signed.send(msg)
        elif roll < 0.2:
            plain.send(msg, force_mavlink1=cls.id < 256)
        else:
            plain.send(msg)
        packet = bytearray(sink.packets.pop())
        roll = rng.random()
        if roll < 0.1:
            packet[int(rng.integers(1, len(packet)))] ^= 0x5A  # corrupt a byte
        elif roll < 0.15:
            packet = packet[: int(rng.integers(1, len(packet)))]  # truncated
        elif roll < 0.2:
            parts.append(bytes(rng.integers(0, 256, int(rng.integers(1, 20))).astype(np.uint8)))
        elif roll < 0.22:
            packet[2] |= 0x04  # an incompat flag nobody knows
        parts.append(bytes(packet))
    return parts


@pytest.mark.parametrize("key", [None, bytes(range(32))])
def test_a_damaged_stream_parses_as_with_pymavlink(key):
    """With a key, unsigned packets but HEARTBEAT are refused (pymavlink's verdicts on the
    signed ones stand too); without, signed packets decode unchecked."""
    rng = np.random.default_rng(11)
    stream = _damaged_stream(rng)
    chunks = rng.integers(1, 300, len(stream))
    results = []
    for cls in (FastMAVLink, mavlink.MAVLink):
        mav = cls(None)
        mav.robust_parsing = True
        if key is not None:
            mav.signing.secret_key = key
            mav.signing.allow_unsigned_callback = lambda _mav, msgid: msgid == 0
        seen = []
        pos = 0
        for n in chunks:  # in odd chunks, as a socket delivers them
            if pos >= len(stream):
                break
            msg = mav.parse_char(stream[pos : pos + n])
            pos += n
            while msg is not None:
                seen.append(_described(msg))
                msg = mav.parse_char(b"")
        results.append((seen, mav.total_receive_errors, mav.total_packets_received,
                        mav.total_bytes_received))
    fast, slow = results
    assert fast == slow
    kinds = [entry[0] for entry in fast[0]]
    assert "BAD_DATA" in kinds
    assert len(set(kinds)) > 50 if key is None else "HEARTBEAT" in kinds


def test_signed_links_still_sign():
    fast, fast_out, slow, slow_out = _pair()
    for mav in (fast, slow):
        mav.signing.secret_key = bytes(range(32))
        mav.signing.sign_outgoing = True
        mav.signing.timestamp = 1000
    msg = mavlink.MAVLink_heartbeat_message(2, 3, 4, 5, 6, 3)
    fast.send(msg)
    slow.send(msg)
    assert fast_out.packets == slow_out.packets
    assert fast_out.packets[0][2] & mavlink.MAVLINK_IFLAG_SIGNED


_BY_NAME = {cls.msgname: cls for cls in mavlink.mavlink_map.values()}


def _read(stream: bytes, chunks, key: bytes | None, records: bool) -> tuple[list[tuple], int]:
    """Every message of ``stream`` delivered in ``chunks``, as (type, field values, system,
    component, packet), and how many came as records: read the driver's way
    (``read_record`` where the parser holds nothing, ``parse_char`` for the rest) or with
    pymavlink alone."""
    mav = FastMAVLink(None) if records else mavlink.MAVLink(None)
    mav.robust_parsing = True
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.allow_unsigned_callback = lambda _mav, msgid: msgid == 0
    buf, pos, seen, start, read = bytearray(), 0, [], 0, 0
    for n in chunks:
        buf += stream[start : start + n]
        start += n
        while True:
            found = None
            if records and mav.buf_index == len(mav.buf) and pos < len(buf):
                found = mav.read_record(buf, pos)
            if found is not None:
                msg, pos = found
                read += isinstance(msg, MessageRecord)
            else:  # the driver hands pymavlink a chunk at a time (smaller here: more turns)
                msg = mav.parse_char(buf[pos : pos + 64])
                pos = min(pos + 64, len(buf))
            if msg is None:
                if pos >= len(buf):
                    break
                continue
            seen.append(_summary(msg))
    return seen, read


@pytest.mark.parametrize("key", [None, bytes(range(32))])
def test_records_read_what_pymavlink_decodes(key):
    """Read the driver's way, a damaged stream (and every message type, cleanly) gives the
    messages, fields and bad-data verdicts pymavlink gives; most packets come as records."""
    rng = np.random.default_rng(12)
    sink = _Sink()
    plain = mavlink.MAVLink(sink, srcSystem=4, srcComponent=9)
    for cls in _plain_types():
        plain.send(_random_message(cls, rng))
    clean, parts = b"".join(sink.packets), _damaged_parts(rng)
    damaged = b"".join(parts)
    # All at once, packet by packet as the in-memory link delivers them (the parser takes
    # over after each bad one and hands back when it is empty), in odd chunks as a socket.
    for stream, chunks in ((clean, [len(clean)]), (damaged, [len(damaged)]),
                           (damaged, [len(part) for part in parts]),
                           (damaged, rng.integers(1, 300, len(damaged)))):
        fast, records = _read(stream, chunks, key, records=True)
        assert fast == _read(stream, chunks, key, records=False)[0]
        assert len(fast) > 250
        if key is not None:
            assert records == 0  # signing: pymavlink checks every packet
        elif stream is clean or len(chunks) == len(parts):
            assert records > len(fast) // 2


def test_parse_records_gives_what_parse_buffer_gives():
    """The SITL's read of each arrival: the damaged stream delivered packet by packet reads
    the same through parse_records as through pymavlink's parse_buffer."""
    parts = _damaged_parts(np.random.default_rng(13))
    fast, slow = FastMAVLink(None), mavlink.MAVLink(None)
    fast.robust_parsing = slow.robust_parsing = True
    got, want, records = [], [], 0
    for part in parts:
        read = fast.parse_records(part)
        records += sum(isinstance(msg, MessageRecord) for msg in read)
        got += [_summary(msg) for msg in read]
        want += [_summary(msg) for msg in slow.parse_buffer(part) or ()]
    assert got == want
    assert records > len(got) // 2


def _summary(msg) -> tuple:
    if msg.get_type() == "BAD_DATA":
        return ("BAD_DATA", bytes(msg.data), msg.reason)
    known = _BY_NAME.get(msg.get_type())
    fields = msg.to_dict() if known is None else [getattr(msg, n) for n in known.fieldnames]
    return (msg.get_type(), fields, msg.get_srcSystem(), msg.get_srcComponent(),
            bytes(msg.get_msgbuf()))
