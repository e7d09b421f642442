"""The driver's geofence upload against a scripted autopilot: the mission protocol's fence
plan, the parameters and the enable command, and the clear failures when the vehicle refuses
or does not answer."""

import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.vehicle import frames
from behaviors.ports import CommandStatus

FENCE = mavlink.MAV_MISSION_TYPE_FENCE
HOME = (47.397742, 8.545594, 488.0)
SQUARE = [(-50.0, -50.0), (50.0, -50.0), (50.0, 50.0), (-50.0, 50.0)]
BEAT = {"custom_mode": 0}  # ArduPilot, STABILIZE


def _connect(rig):
    peer = rig.peer
    peer.heartbeat(**BEAT)
    peer.send(peer.mav.home_position_encode(
        round(HOME[0] * 1e7), round(HOME[1] * 1e7), round(HOME[2] * 1e3), 0, 0, 0,
        [1, 0, 0, 0], 0, 0, 0))
    rig.tick()
    peer.drain()


def _sent(rig, kind):
    return [m for m in rig.peer.received if m.get_type() == kind]


def _request(rig, seq):
    rig.peer.send(rig.peer.mav.mission_request_int_encode(255, 190, seq, FENCE))
    rig.tick()


def test_the_fence_plan_is_sent_item_by_item_about_the_vehicles_home(rig):
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, 60.0)
    rig.tick()
    [count] = _sent(rig, "MISSION_COUNT")
    assert (count.count, count.mission_type) == (4, FENCE)
    for seq in range(4):
        _request(rig, seq)
    items = _sent(rig, "MISSION_ITEM_INT")
    assert [i.seq for i in items] == [0, 1, 2, 3]
    for item, (x, y) in zip(items, SQUARE, strict=True):
        assert item.command == mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
        assert item.frame == mavlink.MAV_FRAME_GLOBAL and item.mission_type == FENCE
        assert item.param1 == 4
        east, north = frames.geodetic_to_local(item.x * 1e-7, item.y * 1e-7, *HOME[:2])
        assert (east, north) == pytest.approx((x, y), abs=0.02)
    assert handle.status is CommandStatus.IN_PROGRESS
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED,
                                                  FENCE))
    rig.tick()
    sets = _sent(rig, "PARAM_SET")
    assert [s.param_id for s in sets] == ["FENCE_ALT_MAX"]
    rig.peer.send(rig.peer.mav.param_value_encode(b"FENCE_ALT_MAX", 60.0,
                                                  mavlink.MAV_PARAM_TYPE_REAL32, 40, 3))
    rig.tick()
    fence_type = _sent(rig, "PARAM_SET")[-1]
    assert (fence_type.param_id, fence_type.param_value) == ("FENCE_TYPE", 5.0)
    rig.peer.send(rig.peer.mav.param_value_encode(b"FENCE_TYPE", 5.0,
                                                  mavlink.MAV_PARAM_TYPE_INT8, 40, 4))
    rig.tick()
    [enable] = rig.peer.commands(mavlink.MAV_CMD_DO_FENCE_ENABLE)
    assert enable.param1 == 1
    rig.peer.ack(mavlink.MAV_CMD_DO_FENCE_ENABLE)
    rig.tick()
    # The breach action stays the autopilot's: read and reported, not set.
    [read] = _sent(rig, "PARAM_REQUEST_READ")
    assert (read.param_id, read.param_index) == ("FENCE_ACTION", -1)
    rig.peer.send(rig.peer.mav.param_value_encode(b"FENCE_ACTION", 0.0,
                                                  mavlink.MAV_PARAM_TYPE_INT8, 40, 5))
    rig.tick()
    assert handle.status is CommandStatus.ACCEPTED
    assert len(_sent(rig, "PARAM_SET")) == 2
    record = rig.vehicle.fence_upload
    assert record.uploaded and record.vertices == 4 and record.max_altitude == 60.0
    assert record.action == ("FENCE_ACTION", 0)
    assert record.describe() == (
        "geofence uploaded to the autopilot: inclusion polygon of 4 vertices, ceiling 60 m "
        "above home; FENCE_TYPE 5, FENCE_ALT_MAX 60, enabled (MAV_CMD_DO_FENCE_ENABLE); "
        "FENCE_ACTION 0 (report only) on a breach: the autopilot will not act; set "
        "FENCE_ACTION on it to have it keep the area")


def test_a_refused_fence_plan_ends_the_upload_with_the_autopilots_answer(rig):
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, None)
    rig.tick()
    _request(rig, 0)
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_NO_SPACE,
                                                  FENCE))
    rig.tick()
    assert handle.status is CommandStatus.DENIED
    assert handle.reason == "fence plan: the autopilot answered MISSION_ACK MAV_MISSION_NO_SPACE"
    assert not _sent(rig, "PARAM_SET"), "nothing is enabled after a refusal"
    text = rig.vehicle.fence_upload.describe()
    assert text.startswith("geofence upload failed (denied): ") and "NO_SPACE" in text


def test_an_unanswered_upload_is_retried_then_cancelled(rig):
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, None)
    rig.run(8.9, heartbeat=BEAT)
    assert handle.status is CommandStatus.PENDING
    rig.run(0.2, heartbeat=BEAT)
    assert handle.status is CommandStatus.TIMED_OUT
    assert len(_sent(rig, "MISSION_COUNT")) == 6, "the first and 5 retries, 1.5 s apart"
    [cancel] = _sent(rig, "MISSION_ACK")
    assert (cancel.type, cancel.mission_type) == (
        mavlink.MAV_MISSION_OPERATION_CANCELLED, FENCE)
    assert "no MISSION_REQUEST from the autopilot" in handle.reason


def test_a_parameter_the_autopilot_keeps_fails_the_upload(rig):
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, 60.0)
    rig.tick()
    for seq in range(4):
        _request(rig, seq)
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED,
                                                  FENCE))
    rig.tick()
    for _ in range(4):  # each PARAM_SET answered with the old value
        rig.peer.send(rig.peer.mav.param_value_encode(b"FENCE_ALT_MAX", 100.0,
                                                      mavlink.MAV_PARAM_TYPE_REAL32, 40, 3))
        rig.tick()
    assert handle.status is CommandStatus.DENIED
    assert handle.reason.endswith("the autopilot kept FENCE_ALT_MAX = 100 (asked for 60)")
    assert len(_sent(rig, "PARAM_SET")) == 4


def test_without_a_link_the_upload_ends_at_once(rig):
    handle = rig.vehicle.upload_fence(SQUARE, None)
    assert handle.status is CommandStatus.TIMED_OUT
    assert rig.vehicle.fence_upload.handle is handle


def test_px4_gets_the_plan_and_ceiling_only_and_its_integer_action_is_read_bytewise(rig):
    peer = rig.peer
    beat = {"custom_mode": 0x03040000, "autopilot": mavlink.MAV_AUTOPILOT_PX4}
    peer.heartbeat(**beat)
    peer.send(peer.mav.home_position_encode(
        round(HOME[0] * 1e7), round(HOME[1] * 1e7), round(HOME[2] * 1e3), 0, 0, 0,
        [1, 0, 0, 0], 0, 0, 0))
    rig.tick()
    handle = rig.vehicle.upload_fence(SQUARE, 45.0)
    rig.tick()
    for seq in range(4):
        _request(rig, seq)
    item = _sent(rig, "MISSION_ITEM_INT")[1]
    east, north = frames.geodetic_to_local(item.x * 1e-7, item.y * 1e-7, *HOME[:2], "px4")
    assert (east, north) == pytest.approx(SQUARE[1], abs=0.02), "PX4's own projection"
    peer.send(peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED, FENCE))
    rig.tick()
    [ceiling] = _sent(rig, "PARAM_SET")
    assert (ceiling.param_id, ceiling.param_value) == ("GF_MAX_VER_DIST", 45.0)
    peer.send(peer.mav.param_value_encode(b"GF_MAX_VER_DIST", 45.0,
                                          mavlink.MAV_PARAM_TYPE_REAL32, 900, 1))
    rig.tick()
    [read] = _sent(rig, "PARAM_REQUEST_READ")
    assert read.param_id == "GF_ACTION"
    return_mode = struct.unpack("<f", struct.pack("<i", 3))[0]  # PX4: the int's bytes
    peer.send(peer.mav.param_value_encode(b"GF_ACTION", return_mode,
                                          mavlink.MAV_PARAM_TYPE_INT32, 900, 2))
    rig.tick()
    assert handle.status is CommandStatus.ACCEPTED, handle.reason
    assert not rig.peer.commands(mavlink.MAV_CMD_DO_FENCE_ENABLE), "PX4 needs no enabling"
    assert rig.vehicle.fence_upload.action == ("GF_ACTION", 3)
    assert rig.vehicle.fence_upload.describe().endswith("GF_ACTION 3 (Return) on a breach")
