"""The SITL's links: corrupt bytes on the in-memory link, UDP and TCP on 127.0.0.1."""

from __future__ import annotations

import select
import socket

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl
from sitl.copter.gcs import MiniGcs
from sitl.transports import TcpServer, UdpEndpoint, parse_address


class _Sink:
    def __init__(self) -> None:
        self.data = b""

    def write(self, data: bytes) -> None:
        self.data += data


def packet(build) -> bytes:
    """Bytes of one MAVLink 2 packet from a GCS (sysid 255)."""
    sink = _Sink()
    build(mavlink.MAVLink(sink, 255, 190))
    return sink.data


def test_corrupt_bytes_are_skipped_and_counted():
    sim = Sitl()
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)
    heartbeat = packet(lambda m: m.heartbeat_send(6, 8, 0, 0, 0))
    arm = packet(lambda m: m.command_long_send(1, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0))
    broken = bytearray(arm)
    broken[12] ^= 0xFF  # a flipped payload byte: bad CRC
    noise = bytes(range(7, 250, 3))
    link.gcs.write(noise + heartbeat + bytes(broken) + noise[:17])
    for _ in range(int(sim.settings.arming_settle_time / 0.05) + 2):
        sim.step(0.05)
        gcs.poll()
    assert gcs.counts["HEARTBEAT"] > 0  # the good heartbeat opened the link
    assert gcs.acks(400) == []  # the corrupted command was not obeyed
    assert sim.corrupt_bytes > 0
    link.gcs.write(noise + arm)
    sim.step(0.05)
    gcs.poll()
    assert gcs.acks(400) == [mavlink.MAV_RESULT_ACCEPTED]
    assert sim.truth.armed


class _SocketClient:
    """read/write over a connected socket, waiting briefly for data (loopback is fast but
    not synchronous)."""

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock

    def write(self, data: bytes) -> None:
        self.sock.sendall(data)

    def read(self) -> bytes:
        chunks = []
        while select.select([self.sock], [], [], 0.02)[0]:
            data = self.sock.recv(65536)
            if not data:
                break
            chunks.append(data)
        return b"".join(chunks)


def _exchange(sim: Sitl, gcs: MiniGcs, until, steps: int = 200) -> bool:
    for _ in range(steps):
        sim.step(0.05)
        gcs.poll()
        if until():
            return True
    return False


def test_udp_server_answers_the_client_that_spoke():
    sim = Sitl()
    server = UdpEndpoint("127.0.0.1", 0)
    sim.attach(server)
    client_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        client_sock.connect(server.address)
        gcs = MiniGcs(_SocketClient(client_sock))
        for _ in range(5):
            sim.step(0.05)
        assert gcs.poll() == []  # nothing before we speak
        gcs.heartbeat()
        gcs.set_interval(mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 10)
        assert _exchange(sim, gcs, lambda: "GLOBAL_POSITION_INT" in gcs.last)
        assert gcs.acks(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL) == [mavlink.MAV_RESULT_ACCEPTED]
        assert gcs.last["HEARTBEAT"].autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    finally:
        client_sock.close()
        sim.close()
    assert server.closed


def test_tcp_server_serves_each_client():
    sim = Sitl(autopilot="px4")
    server = TcpServer("127.0.0.1", 0)
    client_sock = socket.create_connection(server.address)
    try:
        clients = []
        for _ in range(100):
            clients += server.accept()
            if clients:
                break
            select.select([], [], [], 0.01)
        assert len(clients) == 1
        sim.attach(clients[0])
        gcs = MiniGcs(_SocketClient(client_sock))
        assert _exchange(sim, gcs, lambda: "ATTITUDE" in gcs.last and "HEARTBEAT" in gcs.last)
        assert gcs.last["HEARTBEAT"].autopilot == mavlink.MAV_AUTOPILOT_PX4
    finally:
        client_sock.close()
        sim.close()
        server.close()


def test_parse_address_explains_what_is_wrong():
    assert parse_address("127.0.0.1:14550") == ("127.0.0.1", 14550)
    for bad in ("127.0.0.1", ":14550", "127.0.0.1:x", "127.0.0.1:70000"):
        try:
            parse_address(bad)
        except ValueError as exc:
            assert str(exc)
        else:
            raise AssertionError(f"{bad!r} accepted")


def test_a_tcp_client_is_greeted_before_it_speaks():
    # As ArduPilot SITL does: a plain pymavlink wait_heartbeat() on tcp: gets one at once.
    sim = Sitl()
    server = TcpServer("127.0.0.1", 0)
    client_sock = socket.create_connection(server.address)
    try:
        for _ in range(100):
            clients = server.accept()
            if clients:
                break
            select.select([], [], [], 0.01)
        sim.attach(clients[0])
        gcs = MiniGcs(_SocketClient(client_sock))  # never sends anything
        assert _exchange(sim, gcs, lambda: "HEARTBEAT" in gcs.last, steps=5)
        assert gcs.last["HEARTBEAT"].autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    finally:
        client_sock.close()
        sim.close()
        server.close()


def test_udp_out_sends_unasked_then_answers_whoever_speaks():
    # PX4 SITL sends to 14540 / 14550 before anyone speaks; MAVSDK's udpin: listens there.
    listener = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    listener.bind(("127.0.0.1", 0))
    sim = Sitl(autopilot="px4")
    out = UdpEndpoint("127.0.0.1", 0, peer=listener.getsockname())
    sim.attach(out)
    try:
        gcs = MiniGcs(_SocketClient(listener))
        assert _exchange(sim, gcs, lambda: "HEARTBEAT" in gcs.last, steps=5)
        # The listener answers from its own address: the vehicle replies there.
        listener.connect(out.address)
        gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert _exchange(sim, gcs, lambda: "AUTOPILOT_VERSION" in gcs.last, steps=20)
    finally:
        listener.close()
        sim.close()


def _accept(server: TcpServer) -> list:
    for _ in range(200):
        clients = server.accept()
        if clients:
            return clients
        select.select([], [], [], 0.01)
    raise AssertionError("no client connected")


def test_a_client_that_reconnects_mid_flight_finds_the_vehicle_where_it_left_it():
    sim = Sitl()
    server = TcpServer("127.0.0.1", 0)
    first = socket.create_connection(server.address)
    try:
        sim.attach(_accept(server)[0])
        gcs = MiniGcs(_SocketClient(first))
        gcs.heartbeat()
        _exchange(sim, gcs, lambda: False, steps=int(sim.settings.arming_settle_time / 0.05) + 2)
        gcs.set_mode(4)  # GUIDED
        gcs.arm()
        gcs.takeoff(10.0)
        assert _exchange(sim, gcs, lambda: sim.truth.position[2] > 9.7, steps=400)
        gcs.goto_ned(0.0, 20.0, -10.0)
        assert _exchange(sim, gcs, lambda: sim.truth.position[0] > 19.5, steps=400)
        first.close()  # the ground station goes away mid-flight
        for _ in range(200):  # 10 s without it
            sim.step(0.05)
        assert len(sim.server.links) == 0
        second = socket.create_connection(server.address)
        try:
            sim.attach(_accept(server)[0])
            gcs = MiniGcs(_SocketClient(second))
            gcs.set_interval(mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 5)
            assert _exchange(sim, gcs, lambda: "LOCAL_POSITION_NED" in gcs.last, steps=40)
            where = gcs.last["LOCAL_POSITION_NED"]
            assert abs(where.y - 20.0) < 0.5 and abs(where.x) < 0.5 and abs(where.z + 10) < 0.5
            heartbeat = gcs.last["HEARTBEAT"]
            assert heartbeat.custom_mode == 4
            assert heartbeat.base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        finally:
            second.close()
    finally:
        first.close()
        sim.close()
        server.close()
