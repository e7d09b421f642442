"""What a ground station or SDK asks a vehicle it has just met (QGroundControl's
InitialConnectStateMachine, MAVSDK's Info, MAVProxy's start), answered by the embedded SITL as
each autopilot answers: the message, or a refusal in a COMMAND_ACK matched by command id,
never silence and never ACCEPTED for a message that does not come. Over the in-memory link."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as C

from sitl import Sitl
from sitl.copter import protocol_version
from sitl.copter.gcs import MiniGcs
from sitl.copter.telemetry import build_hash, custom_versions
from tests.sitl.test_sitl_ground_station import connect

DT = 0.05
# What the vehicle cannot send: ArduPilot fails the request, PX4 denies it.
REFUSED = {"ardupilot": C.MAV_RESULT_FAILED, "px4": C.MAV_RESULT_DENIED}
# What ground stations and SDKs ask for on connecting that the simulator does not have (some
# are not in pymavlink's dialect: their ids).
NOT_SERVED = {
    "AVAILABLE_MODES (QGroundControl's standard modes)": 435,
    "COMPONENT_METADATA (QGroundControl's component information)": 397,
    "COMPONENT_INFORMATION (its fallback)": 395,
    "GIMBAL_MANAGER_INFORMATION (QGroundControl's gimbal discovery)": 280,
    "CAMERA_INFORMATION": C.MAVLINK_MSG_ID_CAMERA_INFORMATION,
    "FLIGHT_INFORMATION (MAVSDK's Info)": C.MAVLINK_MSG_ID_FLIGHT_INFORMATION,
}


@pytest.fixture
def decodes_protocol_version(monkeypatch):
    """Teach this process's pymavlink PROTOCOL_VERSION, which its definitions lack."""
    monkeypatch.setitem(C.mavlink_map, protocol_version.MSG_ID, protocol_version.message_class())


def ask(sim: Sitl, gcs: MiniGcs, command: int, *params: float) -> tuple[int, list]:
    """Send a command; (the result of its COMMAND_ACK, what else arrived in 0.5 s)."""
    gcs.received.clear()
    gcs.command(command, *params)
    for _ in range(10):
        sim.step(DT)
        gcs.poll()
    results = gcs.acks(command)
    assert len(results) == 1, f"{len(results)} COMMAND_ACKs for command {command}"
    return results[0], [m for m in gcs.received if m.get_type() != "COMMAND_ACK"]


def of_type(msgs: list, name: str) -> list:
    return [m for m in msgs if m.get_type() == name]


# ----------------------------------------------------------------------------- AUTOPILOT_VERSION
def test_the_git_hash_is_encoded_as_each_autopilot_does():
    commit = "0123456789abcdef0123456789abcdef01234567"
    # ArduPilot: the first 8 characters as text.
    assert custom_versions("ardupilot", commit) == (list(b"01234567"), [0] * 8)
    # PX4: the first 16 hex digits as a little-endian uint64, the flight field's low 3 bytes
    # being the vendor version (0.0.0); read back reversed as hex, as QGroundControl does.
    flight, middleware = custom_versions("px4", commit)
    assert bytes(reversed(flight)).hex() == "0123456789000000"
    assert bytes(reversed(middleware)).hex() == "0123456789abcdef"
    assert custom_versions("px4", None) == ([0] * 8, [0] * 8)  # no checkout: no hash claimed


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_autopilot_version_carries_this_codes_git_hash(autopilot):
    sim, gcs = connect(autopilot)
    result, msgs = ask(sim, gcs, C.MAV_CMD_REQUEST_MESSAGE, C.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    assert result == C.MAV_RESULT_ACCEPTED
    (version,) = of_type(msgs, "AUTOPILOT_VERSION")
    commit = build_hash()
    assert commit is not None, "the tests run from a git checkout"
    flight, middleware = custom_versions(autopilot, commit)
    assert list(version.flight_custom_version) == flight
    assert list(version.middleware_custom_version) == middleware
    assert version.flight_sw_version >> 24 == {"ardupilot": 4, "px4": 1}[autopilot]
    assert version.flight_sw_version & 0xFF == C.FIRMWARE_VERSION_TYPE_OFFICIAL
    if autopilot == "ardupilot":
        assert bytes(version.flight_custom_version).decode() == commit[:8]
        assert version.middleware_sw_version == 0 and version.uid == 0
    else:
        assert version.middleware_sw_version == version.flight_sw_version
        assert version.uid == sim.settings.system_id
    # No operating system, board, USB ids or hardware UID of its own to report.
    assert version.os_sw_version == version.board_version == 0
    assert version.vendor_id == version.product_id == 0
    assert not any(version.os_custom_version) and not any(version.uid2)


@pytest.mark.parametrize("autopilot, param1, result", [
    ("ardupilot", 1, C.MAV_RESULT_ACCEPTED),
    ("ardupilot", 0, C.MAV_RESULT_FAILED),  # handle_command_request_autopilot_capabilities
    ("px4", 1, C.MAV_RESULT_ACCEPTED),
    ("px4", 0, C.MAV_RESULT_ACCEPTED),
])
def test_request_autopilot_capabilities(autopilot, param1, result):
    sim, gcs = connect(autopilot)
    got, msgs = ask(sim, gcs, C.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, param1)
    assert got == result
    assert len(of_type(msgs, "AUTOPILOT_VERSION")) == (result == C.MAV_RESULT_ACCEPTED)


@pytest.mark.parametrize("autopilot, answered", [("ardupilot", True), ("px4", False)])
def test_autopilot_version_request_message_is_ardupilots(autopilot, answered):
    sim, gcs = connect(autopilot)
    gcs.received.clear()
    gcs.mav.autopilot_version_request_send(1, 1)
    for _ in range(10):
        sim.step(DT)
        gcs.poll()
    assert len(of_type(gcs.received, "AUTOPILOT_VERSION")) == answered


# ----------------------------------------------------------------------------- PROTOCOL_VERSION
@pytest.mark.parametrize("command, params", [
    (C.MAV_CMD_REQUEST_MESSAGE, (protocol_version.MSG_ID,)),
    (C.MAV_CMD_REQUEST_PROTOCOL_VERSION, (1,)),
])
def test_px4_answers_protocol_version(decodes_protocol_version, command, params):
    sim, gcs = connect("px4")
    result, msgs = ask(sim, gcs, command, *params)
    assert result == C.MAV_RESULT_ACCEPTED
    (answer,) = of_type(msgs, "PROTOCOL_VERSION")
    assert (answer.version, answer.min_version, answer.max_version) == (200, 100, 200)
    assert answer.get_srcSystem() == 1 and answer.get_srcComponent() == 1


@pytest.mark.parametrize("command, params, result", [
    (C.MAV_CMD_REQUEST_MESSAGE, (protocol_version.MSG_ID,), C.MAV_RESULT_FAILED),
    (C.MAV_CMD_REQUEST_PROTOCOL_VERSION, (1,), C.MAV_RESULT_UNSUPPORTED),
])
def test_ardupilot_has_no_protocol_version(decodes_protocol_version, command, params, result):
    sim, gcs = connect("ardupilot")
    got, msgs = ask(sim, gcs, command, *params)
    assert got == result
    assert not of_type(msgs, "PROTOCOL_VERSION")


# ----------------------------------------------------------------------------- refusals
# Before home: GET_HOME_POSITION is refused on both; REQUEST_MESSAGE HOME_POSITION is
# refused by PX4, and ACCEPTED by ArduPilot, which then sends nothing.
BEFORE_HOME = {"ardupilot": (C.MAV_RESULT_ACCEPTED, C.MAV_RESULT_FAILED),
               "px4": (C.MAV_RESULT_DENIED, C.MAV_RESULT_DENIED)}


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_home_is_refused_until_there_is_one_then_sent(autopilot):
    sim, gcs = connect(autopilot)
    for (command, params), expected in zip(
            ((C.MAV_CMD_REQUEST_MESSAGE, (C.MAVLINK_MSG_ID_HOME_POSITION,)),
             (C.MAV_CMD_GET_HOME_POSITION, ())), BEFORE_HOME[autopilot], strict=True):
        result, msgs = ask(sim, gcs, command, *params)
        assert result == expected, command
        assert not of_type(msgs, "HOME_POSITION")
    while not sim.server.autopilot.position_known:
        sim.step(DT)
        gcs.poll()
    for command, params in ((C.MAV_CMD_REQUEST_MESSAGE, (C.MAVLINK_MSG_ID_HOME_POSITION,)),
                            (C.MAV_CMD_GET_HOME_POSITION, ())):
        result, msgs = ask(sim, gcs, command, *params)
        assert result == C.MAV_RESULT_ACCEPTED, command
        assert of_type(msgs, "HOME_POSITION")


def test_ardupilot_accepts_fence_status_without_a_fence_and_sends_none():
    sim, gcs = connect("ardupilot")
    result, msgs = ask(sim, gcs, C.MAV_CMD_REQUEST_MESSAGE, C.MAVLINK_MSG_ID_FENCE_STATUS)
    assert result == C.MAV_RESULT_ACCEPTED
    assert not of_type(msgs, "FENCE_STATUS")


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
@pytest.mark.parametrize("what", list(NOT_SERVED))
def test_what_the_simulator_does_not_have_is_refused(autopilot, what):
    sim, gcs = connect(autopilot)
    result, msgs = ask(sim, gcs, C.MAV_CMD_REQUEST_MESSAGE, NOT_SERVED[what])
    assert result == REFUSED[autopilot]
    assert not [m for m in msgs if m.get_msgId() == NOT_SERVED[what]]
