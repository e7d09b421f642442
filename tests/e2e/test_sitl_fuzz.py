"""The embedded SITL under fuzz: over 100,000 MAVLink messages of every type of the dialect with
hostile field values (NaN, infinities, extremes, random bytes) plus random and truncated bytes,
sent to `lander sitl`'s TCP port; then a ground station puts back what it changed and the demo
mission is flown live over the same port to a landing.

The fuzz is addressed to the vehicle (target system 1 or broadcast, mostly) so the handlers
see it, with one exception: no arming command. An armed vehicle obeying random targets could
fly into the ground, which is the flight's fault and not the server's, and would leave nothing
to fly the mission with; arming with hostile parameters has its own test
(tests/sitl/test_sitl_ground_station.py). SETUP_SIGNING goes to another system for the same
reason (a random key would lock the ground station out, as it would on a real autopilot).
"""

from __future__ import annotations

import math
import random
import select
import socket
import threading
import time
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.config import apply_overrides, load_mission
from autonomy.runner import fly
from autonomy.runner.world import FlightSeeds, build_sitl, build_terrain
from sitl.copter.gcs import MiniGcs
from sitl.realtime import RealTimeRunner
from sitl.transports import TcpServer

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"
MESSAGES = 100_000
SPEEDUP = 20.0
_ARM = mavlink.MAV_CMD_COMPONENT_ARM_DISARM
_COMMANDS = [c for c in mavlink.enums["MAV_CMD"] if c != _ARM]
_FLOAT32 = [math.nan, math.inf, -math.inf, 0.0, -0.0, 1.0, -1.0, 3.4e38, -3.4e38, 1e-45]
_DOUBLE = [*_FLOAT32, 1.7e308, -1.7e308]
_INT_RANGES = {
    "int8_t": (-(2**7), 2**7 - 1), "uint8_t": (0, 2**8 - 1),
    "int16_t": (-(2**15), 2**15 - 1), "uint16_t": (0, 2**16 - 1),
    "int32_t": (-(2**31), 2**31 - 1), "uint32_t": (0, 2**32 - 1),
    "int64_t": (-(2**63), 2**63 - 1), "uint64_t": (0, 2**64 - 1),
}


class _Buffer:
    def __init__(self) -> None:
        self.chunks: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.chunks.append(bytes(data))


def _scalar(ftype: str, rng: random.Random):
    if ftype in ("float", "double"):
        if rng.random() < 0.6:
            return rng.choice(_FLOAT32 if ftype == "float" else _DOUBLE)
        return rng.gauss(0.0, 10.0 ** rng.randrange(8))
    low, high = _INT_RANGES[ftype]
    pick = rng.random()
    if pick < 0.2:
        return low
    if pick < 0.4:
        return high
    if pick < 0.5:
        return 0
    return rng.randint(low, high)


class _Pools:
    """Hostile values of each field type, drawn once; a field takes one at a random offset
    (an array a run of them), which is far cheaper than drawing each."""

    SIZE = 1 << 13

    def __init__(self, rng: random.Random) -> None:
        self.rng = rng
        self.pools = {
            ftype: [_scalar(ftype, rng) for _ in range(self.SIZE)] * 2
            for ftype in (*_INT_RANGES, "float", "double")
        }

    def value(self, ftype: str, length: int):
        rng = self.rng
        if ftype == "char":
            return rng.randbytes(rng.randint(0, length))
        start = rng.getrandbits(13)
        pool = self.pools[ftype]
        return pool[start:start + length] if length else pool[start]


def hostile_message(cls, pools: _Pools, param_names: list[str]):
    """A message of type ``cls`` with hostile field values, mostly addressed to system 1."""
    rng = pools.rng
    lengths = dict(zip(cls.ordered_fieldnames, cls.array_lengths, strict=True))
    fields = {
        name: pools.value(ftype, lengths[name])
        for name, ftype in zip(cls.fieldnames, cls.fieldtypes, strict=True)
    }
    if "target_system" in fields:
        fields["target_system"] = rng.choice([1, 1, 1, 0, rng.randrange(256)])
    if "target_component" in fields:
        fields["target_component"] = rng.choice([1, 1, 0, rng.randrange(256)])
    if cls in (mavlink.MAVLink_command_long_message, mavlink.MAVLink_command_int_message):
        command = rng.choice(_COMMANDS) if rng.random() < 0.7 else rng.randrange(2**16)
        fields["command"] = command if command != _ARM else 0
    if cls is mavlink.MAVLink_setup_signing_message:
        fields["target_system"] = 200
    if "param_id" in fields and rng.random() < 0.5:
        fields["param_id"] = rng.choice(param_names).encode()
    return cls(**fields)


def fuzz_bytes(rng: random.Random, count: int, param_names: list[str]):
    """(bytes, messages, malformed) for ``count`` messages of every type, round robin, with
    random garbage and truncated or corrupted copies mixed in."""
    out = _Buffer()
    mav = mavlink.MAVLink(out, 255, 190)
    types = sorted(mavlink.mavlink_map.values(), key=lambda c: c.id)
    pools = _Pools(rng)
    malformed = 0
    for i in range(count):
        mav.send(hostile_message(types[i % len(types)], pools, param_names))
        if rng.random() < 0.02:
            packet = out.chunks.pop()
            roll = rng.random()
            if roll < 0.4:
                out.chunks.append(packet[: rng.randrange(1, len(packet))])
            elif roll < 0.8:
                flipped = bytearray(packet)
                flipped[rng.randrange(len(flipped))] ^= 0xFF
                out.chunks.append(bytes(flipped))
            else:
                out.chunks.append(rng.randbytes(64))
            malformed += 1
    return b"".join(out.chunks), count, malformed


class _Socket:
    """MiniGcs's endpoint over a connected socket, reading what is there."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock

    def write(self, data: bytes) -> None:
        self.sock.sendall(data)

    def read(self) -> bytes:
        chunks = []
        while select.select([self.sock], [], [], 0)[0]:
            data = self.sock.recv(1 << 20)
            if not data:
                break
            chunks.append(data)
        return b"".join(chunks)


def until(gcs: MiniGcs, condition, timeout: float) -> bool:
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        gcs.poll()
        if condition():
            return True
        time.sleep(0.01)
    return False


@pytest.fixture
def served_demo_sitl():
    """The demo mission's SITL (its world, wind and home) served on TCP at SPEEDUP."""
    mission = load_mission(DEMO)
    seeds = FlightSeeds.derive(mission.seed)
    sitl = build_sitl(mission, build_terrain(mission, seeds.terrain), seeds.sitl)
    server = TcpServer("127.0.0.1", 0)
    runner = RealTimeRunner(sitl, tcp=[server], speedup=SPEEDUP)
    stop = threading.Event()
    thread = threading.Thread(target=runner.run, kwargs={"should_stop": stop.is_set},
                              daemon=True)
    thread.start()
    yield mission, sitl, server.address[1]
    stop.set()
    thread.join(timeout=10)
    runner.close()


@pytest.mark.timeout(300)
def test_a_fuzzed_sitl_keeps_running_and_then_flies_the_demo_mission(served_demo_sitl, tmp_path):
    mission, sitl, port = served_demo_sitl
    sock = socket.create_connection(("127.0.0.1", port))
    gcs = MiniGcs(_Socket(sock))
    gcs.keep = False  # the fuzz answers are many; only `last` and `counts` are kept
    try:
        gcs.heartbeat()
        gcs.param_request_list()
        # The whole list first: a list item arriving later would hide a read's answer.
        names = _param_names(sitl)
        assert until(gcs, lambda: gcs.counts["PARAM_VALUE"] >= len(names), 30)
        # Read the parameters by hand (keep=False): one PARAM_VALUE per read.
        before: dict[str, float] = {}
        for name in names:
            gcs.param_read(name)
            assert until(gcs, lambda n=name: gcs.last["PARAM_VALUE"].param_id == n, 10)
            before[name] = gcs.last["PARAM_VALUE"].param_value
        data, sent, malformed = fuzz_bytes(random.Random(2026), MESSAGES, list(before))
        assert sent >= 100_000
        for start in range(0, len(data), 1 << 16):
            sock.sendall(data[start:start + (1 << 16)])
            gcs.poll()  # keep reading, as a ground station does

        # Everything sent before this command has been handled once its answer comes.
        gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert until(gcs, lambda: gcs.last.get("COMMAND_ACK") is not None
                     and gcs.last["COMMAND_ACK"].command == mavlink.MAV_CMD_REQUEST_MESSAGE, 120)
        server = sitl.server
        assert server.handler_errors == 0  # no handler raised on any of it
        assert server.corrupt_bytes > 0 or sum(
            link.corrupt_packets for link in server.links) > 0  # malformed input counted
        assert malformed > 0
        truth = sitl.truth
        assert not truth.armed and not truth.crashed

        # A ground station puts back what the fuzz changed: mode, plans, parameters.
        gcs.set_mode(0)  # STABILIZE
        gcs.mav.mission_clear_all_send(1, 1, mavlink.MAV_MISSION_TYPE_ALL)
        for name, value in before.items():
            gcs.param_set(name, value, _param_type(sitl, name))
            assert until(gcs, lambda n=name, v=value: gcs.last["PARAM_VALUE"].param_id == n
                         and gcs.last["PARAM_VALUE"].param_value == v, 10), name
    finally:
        sock.close()

    live = apply_overrides(mission, {"vehicle.connection": f"tcp:127.0.0.1:{port}",
                                     "time_limit": 600.0})
    result = fly(live, out_dir=tmp_path)
    assert result.outcome == "landed_unjudged", result.summary["stop_reason"]
    assert sitl.truth.landed and not sitl.truth.armed and not sitl.truth.crashed
    assert sitl.server.handler_errors == 0


def _param_names(sitl) -> list[str]:
    return [p.name for p in sitl.autopilot.params.rows]


def _param_type(sitl, name: str) -> int:
    table = sitl.autopilot.params
    return table.rows[table.find(name)].type
