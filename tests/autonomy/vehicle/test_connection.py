"""connect(): URLs, clear errors for bad ones, signing keys, telemetry logs."""

from __future__ import annotations

import hashlib
import socket
import time

import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.clock import SimClock
from autonomy.errors import UserError
from autonomy.vehicle import MavlinkVehicle, connect, signing_key_from_text
from autonomy.vehicle.connection import MemoryTransport
from autonomy.vehicle.tlog import TlogWriter
from behaviors.ports import CommandStatus
from sitl.link import MemoryLink


@pytest.mark.parametrize(
    "url, words",
    [
        ("ftp://example.com", "unknown link"),
        ("bluetooth:drone", "unknown link"),
        ("udpin:127.0.0.1", "HOST:PORT"),
        ("tcp:127.0.0.1:notaport", "HOST:PORT"),
        ("udpout:127.0.0.1:70000", "HOST:PORT"),
        ("sim:ardupilot", "sim://"),
        ("sim://betaflight", "'ardupilot' or 'px4'"),
        ("sim://px4?speed=3", "unknown option"),
        ("/dev/this-serial-port-does-not-exist", "cannot open"),
        ("", "empty"),
        ("udpout:no-such-host.invalid:14550", "unknown host"),
    ],
)
def test_bad_url_is_one_clear_user_error(url, words):
    with pytest.raises(UserError) as err:
        connect(url, SimClock())
    message = str(err.value)
    assert words in message and "\n" not in message


def test_tcp_refused_is_a_user_error():
    # Take an ephemeral port and close it, so nothing listens there.
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()
    with pytest.raises(UserError, match="refused"):
        connect(f"tcp:127.0.0.1:{port}", SimClock())


def test_udp_port_in_use_is_a_user_error():
    busy = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    busy.bind(("127.0.0.1", 0))
    try:
        port = busy.getsockname()[1]
        with pytest.raises(UserError, match="in use"):
            connect(f"udpin:127.0.0.1:{port}", SimClock())
    finally:
        busy.close()


def test_udpin_listens_and_answers_the_sender():
    clock = SimClock()
    vehicle = connect("udpin:127.0.0.1:0", clock)
    try:
        port = vehicle._transport._conn.port.getsockname()[1]
        autopilot = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        autopilot.bind(("127.0.0.1", 0))
        autopilot.setblocking(False)
        mav = mavlink.MAVLink(None, 1, 1)
        beat = mav.heartbeat_encode(
            mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3
        ).pack(mav)
        autopilot.sendto(beat, ("127.0.0.1", port))
        for _ in range(200):  # the datagram is on loopback; poll until it is read
            clock.advance(0.01)
            if not vehicle.poll().link_lost:
                break
        assert vehicle.state.mode == "GUIDED"
        replies = mavlink.MAVLink(None, 0, 0)
        got = []
        for _ in range(200):
            try:
                got += replies.parse_buffer(autopilot.recv(65536)) or []
            except BlockingIOError:
                if got:
                    break
                clock.advance(0.01)
                vehicle.poll()
        assert any(m.get_type() == "COMMAND_LONG" for m in got)  # the stream requests
        autopilot.close()
    finally:
        vehicle.close()


def test_signing_key_text_forms(monkeypatch):
    hexkey = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff"
    assert signing_key_from_text(hexkey) == bytes.fromhex(hexkey)
    assert signing_key_from_text("correct horse") == hashlib.sha256(b"correct horse").digest()
    with pytest.raises(UserError):
        signing_key_from_text("   ")
    with pytest.raises(UserError, match="32 bytes"):
        connect("sim://", SimClock(), signing_key=b"short")


def _signed_peer(link, key: bytes | None):
    mav = mavlink.MAVLink(link.vehicle, 1, 1)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        # MAVLink signing time: 10 us units since 2015-01-01; a new stream must be recent.
        mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    return mav


def test_signed_link_accepts_only_signed_packets():
    key = signing_key_from_text("landing autonomy")
    clock = SimClock()
    link = MemoryLink()
    vehicle = MavlinkVehicle(MemoryTransport(link.gcs), clock, signing_key=key)
    try:
        # Our own packets are signed with the key.
        check = mavlink.MAVLink(None, 0, 0)
        check.signing.secret_key = key
        ours = check.parse_buffer(link.vehicle.read())
        assert ours and all(m._signed for m in ours)

        stranger = _signed_peer(link, None)
        stranger.heartbeat_send(2, 3, 0, 4, 3)
        wrong = _signed_peer(link, signing_key_from_text("not the key"))
        wrong.heartbeat_send(2, 3, 0, 4, 3)
        clock.advance(0.1)
        assert vehicle.poll().link_lost
        assert vehicle.stats.bad_signature == 2

        friend = _signed_peer(link, key)
        friend.signing.link_id = 1  # its own signing stream, whatever the impostor sent
        friend.heartbeat_send(2, 3, 0, 4, 3)
        clock.advance(0.1)
        assert not vehicle.poll().link_lost
    finally:
        vehicle.close()


def test_signing_key_from_environment(monkeypatch):
    monkeypatch.setenv("LANDER_SIGNING_KEY", "from the environment")
    clock = SimClock()
    vehicle = connect("sim://", clock)
    try:
        assert vehicle._mav.signing.secret_key == hashlib.sha256(b"from the environment").digest()
    finally:
        vehicle.close()


def test_tlog_is_read_back_by_pymavlink(tmp_path):
    mav = mavlink.MAVLink(None, 1, 1)
    packets = [
        mav.heartbeat_encode(2, 3, 0, 4, 3).pack(mav),
        mav.local_position_ned_encode(0, 1.0, 2.0, 3.0, 0, 0, 0).pack(mav),
    ]
    path = tmp_path / "logs" / "a.tlog"
    with TlogWriter(path, epoch=1_700_000_000.0) as log:
        log.write(packets[0], 0.5)
        log.write(packets[1], 1.25)
    reader = mavutil.mavlink_connection(str(path))
    first, second = reader.recv_match(), reader.recv_match()
    assert (first.get_type(), second.get_type()) == ("HEARTBEAT", "LOCAL_POSITION_NED")
    assert first._timestamp == pytest.approx(1_700_000_000.5)
    assert second._timestamp == pytest.approx(1_700_000_001.25)
    assert reader.recv_match() is None


def test_tlog_in_an_unwritable_place_is_a_user_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(UserError, match="telemetry log"):
        connect("sim://", SimClock(), tlog_path=blocker / "x.tlog")


def test_tcp_peer_hanging_up_is_a_quiet_link_loss(capsys):
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    clock = SimClock()
    vehicle = connect(f"tcp:127.0.0.1:{server.getsockname()[1]}", clock, link_timeout=1.0)
    try:
        autopilot, _ = server.accept()
        mav = mavlink.MAVLink(None, 1, 1)
        autopilot.sendall(
            mav.heartbeat_encode(
                mavlink.MAV_TYPE_QUADROTOR, mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 4, 3
            ).pack(mav)
        )
        for _ in range(200):
            clock.advance(0.01)
            if not vehicle.poll().link_lost:
                break
        assert vehicle.state.mode == "GUIDED"
        autopilot.close()
        for _ in range(150):
            clock.advance(0.01)
            state = vehicle.poll()
        assert state.link_lost
        assert vehicle.land().status is CommandStatus.TIMED_OUT
        assert capsys.readouterr().out == ""
    finally:
        vehicle.close()
        server.close()
