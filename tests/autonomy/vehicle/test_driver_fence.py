"""The driver's geofence upload against a scripted autopilot: the vehicle's own fence plan
read first (its no-fly zones kept), the mission protocol's fence plan, the parameters and the
enable command, and the clear failures when the vehicle refuses or does not answer."""

import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.vehicle import frames
from behaviors.ports import CommandStatus
from lsm.area import NoFlyCircle

FENCE = mavlink.MAV_MISSION_TYPE_FENCE
HOME = (47.397742, 8.545594, 488.0)
SQUARE = [(-50.0, -50.0), (50.0, -50.0), (50.0, 50.0), (-50.0, 50.0)]
BEAT = {"custom_mode": 0}  # ArduPilot, STABILIZE
REAL32, INT8 = mavlink.MAV_PARAM_TYPE_REAL32, mavlink.MAV_PARAM_TYPE_INT8


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


def _vehicle_fence(rig, items=()):
    """Answer the driver's download of the vehicle's fence plan with ``items`` (fields of
    MISSION_ITEM_INT after seq, before mission_type)."""
    [ask] = _sent(rig, "MISSION_REQUEST_LIST")
    assert ask.mission_type == FENCE
    rig.peer.send(rig.peer.mav.mission_count_encode(255, 190, len(items), FENCE))
    rig.tick()
    for seq, item in enumerate(items):
        request = _sent(rig, "MISSION_REQUEST_INT")[-1]
        assert (request.seq, request.mission_type) == (seq, FENCE)
        rig.peer.send(rig.peer.mav.mission_item_int_encode(255, 190, seq, *item, FENCE))
        rig.tick()
    [ack] = _sent(rig, "MISSION_ACK")
    assert (ack.type, ack.mission_type) == (mavlink.MAV_MISSION_ACCEPTED, FENCE)


def _param(rig, name, value, kind):
    rig.peer.send(rig.peer.mav.param_value_encode(name.encode(), value, kind, 40, 3))
    rig.tick()


def _request(rig, seq):
    rig.peer.send(rig.peer.mav.mission_request_int_encode(255, 190, seq, FENCE))
    rig.tick()


def test_the_fence_plan_is_sent_item_by_item_about_the_vehicles_home(rig):
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, 60.0)
    rig.tick()
    _vehicle_fence(rig)
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
    # Each parameter is read before it is set (its value is put back after the flight).
    for name, before, after, kind in [("FENCE_ALT_MAX", 100.0, 60.0, REAL32),
                                      ("FENCE_TYPE", 7.0, 5.0, INT8)]:
        assert _sent(rig, "PARAM_REQUEST_READ")[-1].param_id == name
        _param(rig, name, before, kind)
        last = _sent(rig, "PARAM_SET")[-1]
        assert (last.param_id, last.param_value) == (name, after)
        _param(rig, name, after, kind)
    assert _sent(rig, "PARAM_REQUEST_READ")[-1].param_id == "FENCE_ENABLE"
    _param(rig, "FENCE_ENABLE", 0.0, INT8)
    [enable] = rig.peer.commands(mavlink.MAV_CMD_DO_FENCE_ENABLE)
    assert enable.param1 == 1
    rig.peer.ack(mavlink.MAV_CMD_DO_FENCE_ENABLE)
    rig.tick()
    # The breach action stays the autopilot's: read and reported, not set.
    read = _sent(rig, "PARAM_REQUEST_READ")[-1]
    assert (read.param_id, read.param_index) == ("FENCE_ACTION", -1)
    _param(rig, "FENCE_ACTION", 0.0, INT8)
    assert handle.status is CommandStatus.ACCEPTED
    assert len(_sent(rig, "PARAM_SET")) == 2
    record = rig.vehicle.fence_upload
    assert record.uploaded and record.vertices == 4 and record.max_altitude == 60.0
    assert record.action == ("FENCE_ACTION", 0)
    assert record.describe() == (
        "geofence uploaded to the autopilot: inclusion polygon of 4 vertices, ceiling 60 m "
        "above home; the vehicle had no fence plan; FENCE_TYPE 5, FENCE_ALT_MAX 60, enabled "
        "(MAV_CMD_DO_FENCE_ENABLE); "
        "FENCE_ACTION 0 (report only) on a breach: the autopilot will not act; set "
        "FENCE_ACTION on it to have it keep the area")


def test_a_refused_fence_plan_ends_the_upload_with_the_autopilots_answer(rig):
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, None)
    rig.tick()
    _vehicle_fence(rig)
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
    rig.tick()
    _vehicle_fence(rig)
    rig.run(8.9, heartbeat=BEAT)
    assert handle.status is CommandStatus.PENDING
    rig.run(0.2, heartbeat=BEAT)
    assert handle.status is CommandStatus.TIMED_OUT
    assert len(_sent(rig, "MISSION_COUNT")) == 6, "the first and 5 retries, 1.5 s apart"
    downloaded, cancel = _sent(rig, "MISSION_ACK")
    assert downloaded.type == mavlink.MAV_MISSION_ACCEPTED
    assert (cancel.type, cancel.mission_type) == (
        mavlink.MAV_MISSION_OPERATION_CANCELLED, FENCE)
    assert "no MISSION_REQUEST from the autopilot" in handle.reason


def test_a_parameter_the_autopilot_keeps_fails_the_upload(rig):
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, 60.0)
    rig.tick()
    _vehicle_fence(rig)
    for seq in range(4):
        _request(rig, seq)
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED,
                                                  FENCE))
    rig.tick()
    _param(rig, "FENCE_ALT_MAX", 100.0, REAL32)  # the read before the set
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
    _vehicle_fence(rig)
    for seq in range(4):
        _request(rig, seq)
    item = _sent(rig, "MISSION_ITEM_INT")[1]
    east, north = frames.geodetic_to_local(item.x * 1e-7, item.y * 1e-7, *HOME[:2], "px4")
    assert (east, north) == pytest.approx(SQUARE[1], abs=0.02), "PX4's own projection"
    peer.send(peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED, FENCE))
    rig.tick()
    assert _sent(rig, "PARAM_REQUEST_READ")[-1].param_id == "GF_MAX_VER_DIST"
    _param(rig, "GF_MAX_VER_DIST", 0.0, REAL32)
    [ceiling] = _sent(rig, "PARAM_SET")
    assert (ceiling.param_id, ceiling.param_value) == ("GF_MAX_VER_DIST", 45.0)
    _param(rig, "GF_MAX_VER_DIST", 45.0, REAL32)
    read = _sent(rig, "PARAM_REQUEST_READ")[-1]
    assert read.param_id == "GF_ACTION"
    return_mode = struct.unpack("<f", struct.pack("<i", 3))[0]  # PX4: the int's bytes
    peer.send(peer.mav.param_value_encode(b"GF_ACTION", return_mode,
                                          mavlink.MAV_PARAM_TYPE_INT32, 900, 2))
    rig.tick()
    assert handle.status is CommandStatus.ACCEPTED, handle.reason
    assert not rig.peer.commands(mavlink.MAV_CMD_DO_FENCE_ENABLE), "PX4 needs no enabling"
    assert rig.vehicle.fence_upload.action == ("GF_ACTION", 3)
    assert rig.vehicle.fence_upload.describe().endswith("GF_ACTION 3 (Return) on a breach")


def _global(command, lat, lon, param1=0.0):
    return (mavlink.MAV_FRAME_GLOBAL, command, 0, 1, param1, 0.0, 0.0, 0.0,
            round(lat * 1e7), round(lon * 1e7), 0.0)


def test_the_vehicles_no_fly_zones_and_return_point_are_uploaded_again(rig):
    # A vehicle whose operator put an inclusion zone, a no-fly triangle, a no-fly circle and
    # a return point on it: the flight's upload replaces the whole plan, so it must carry the
    # no-fly zones and the return point along; the operating area replaces the inclusion.
    inclusion = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION
    exclusion = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    vehicle_plan = [
        *(_global(inclusion, HOME[0] + d, HOME[1] + e, 3.0)
          for d, e in [(-0.01, -0.01), (0.01, -0.01), (0.0, 0.01)]),
        *(_global(exclusion, HOME[0] + 0.002 + d, HOME[1] + e, 3.0)
          for d, e in [(0.0, 0.0), (0.001, 0.0), (0.0, 0.001)]),
        (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 0, 1, 25.0,
         0.0, 0.0, 0.0, round((HOME[0] - 0.003) * 1e7), round(HOME[1] * 1e7), 0.0),
        _global(mavlink.MAV_CMD_NAV_FENCE_RETURN_POINT, HOME[0] + 0.0001, HOME[1]),
    ]
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, None)
    rig.tick()
    _vehicle_fence(rig, vehicle_plan)
    [count] = _sent(rig, "MISSION_COUNT")
    assert count.count == 4 + 5, "the area's 4 vertices, then the 5 items kept"
    for seq in range(9):
        _request(rig, seq)
    items = _sent(rig, "MISSION_ITEM_INT")
    assert [i.command for i in items[:4]] == [inclusion] * 4
    kept = [(i.frame, i.command, i.current, i.autocontinue, i.param1, i.param2, i.param3,
             i.param4, i.x, i.y, i.z) for i in items[4:]]
    assert kept == vehicle_plan[3:], "the vehicle's own items, unchanged and in order"
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED,
                                                  FENCE))
    rig.tick()
    assert rig.vehicle.fence_upload.vehicle_fence == (
        "kept the vehicle's 2 exclusion zones; kept its fence return point; replaced its 1 "
        "inclusion zone by the operating area")
    assert handle.status is CommandStatus.IN_PROGRESS  # on to FENCE_TYPE and the enable


def test_the_missions_no_fly_zones_go_after_the_area_and_before_the_vehicles(rig):
    exclusion = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    vehicle_zone = [_global(exclusion, HOME[0] + 0.002 + d, HOME[1] + e, 3.0)
                    for d, e in [(0.0, 0.0), (0.001, 0.0), (0.0, 0.001)]]
    building = [(10.0, 10.0), (20.0, 10.0), (20.0, 20.0)]
    road = [(-40.0, -5.0), (40.0, -5.0), (40.0, 5.0), (-40.0, 5.0)]
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, None, [building, road])
    rig.tick()
    _vehicle_fence(rig, vehicle_zone)
    [count] = _sent(rig, "MISSION_COUNT")
    assert count.count == 4 + 3 + 4 + 3
    for seq in range(count.count):
        _request(rig, seq)
    items = _sent(rig, "MISSION_ITEM_INT")
    assert [(i.command, i.param1) for i in items[:11]] == (
        [(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 4)] * 4
        + [(exclusion, 3)] * 3 + [(exclusion, 4)] * 4)
    for item, (x, y) in zip(items[4:11], building + road, strict=True):
        assert item.frame == mavlink.MAV_FRAME_GLOBAL
        east, north = frames.geodetic_to_local(item.x * 1e-7, item.y * 1e-7, *HOME[:2])
        assert (east, north) == pytest.approx((x, y), abs=0.02)
    assert [(i.x, i.y) for i in items[11:]] == [(v[8], v[9]) for v in vehicle_zone]
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED,
                                                  FENCE))
    rig.tick()
    assert handle.status is CommandStatus.IN_PROGRESS  # on to FENCE_TYPE and the enable
    assert rig.vehicle.fence_upload.zones == 2


def test_a_missions_no_fly_circle_goes_as_one_circle_item_after_the_polygons(rig):
    exclusion = mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION
    mast = NoFlyCircle(-20.0, 30.0, 12.5)
    building = [(10.0, 10.0), (20.0, 10.0), (20.0, 20.0)]
    _connect(rig)
    rig.vehicle.upload_fence(SQUARE, None, [mast, building])
    rig.tick()
    _vehicle_fence(rig, [])
    [count] = _sent(rig, "MISSION_COUNT")
    assert count.count == 4 + 3 + 1
    for seq in range(count.count):
        _request(rig, seq)
    items = _sent(rig, "MISSION_ITEM_INT")
    assert [(i.command, i.param1) for i in items[4:]] == (
        [(exclusion, 3)] * 3 + [(mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 12.5)])
    circle = items[-1]
    assert circle.frame == mavlink.MAV_FRAME_GLOBAL
    east, north = frames.geodetic_to_local(circle.x * 1e-7, circle.y * 1e-7, *HOME[:2])
    assert (east, north) == pytest.approx((-20.0, 30.0), abs=0.02)
    assert (rig.vehicle.fence_upload.zones, rig.vehicle.fence_upload.circles) == (2, 1)


@pytest.mark.parametrize("answer", ["refused", "silent"])
def test_without_the_vehicles_fence_plan_nothing_is_uploaded(rig, answer):
    # Uploading without having read the vehicle's plan could lift its no-fly zones.
    _connect(rig)
    handle = rig.vehicle.upload_fence(SQUARE, None)
    if answer == "refused":
        rig.tick()
        rig.peer.send(rig.peer.mav.mission_ack_encode(
            255, 190, mavlink.MAV_MISSION_UNSUPPORTED, FENCE))
        rig.tick()
        reason = ("the vehicle's fence plan: the autopilot answered MISSION_ACK "
                  "MAV_MISSION_UNSUPPORTED")
    else:
        rig.run(9.1, heartbeat=BEAT)
        reason = ("the vehicle's fence plan: no MISSION_COUNT from the autopilot after 6 "
                  "attempts 1.5 s apart")
    assert handle.status is (CommandStatus.DENIED if answer == "refused"
                             else CommandStatus.TIMED_OUT)
    assert handle.reason == reason
    assert not _sent(rig, "MISSION_COUNT") and not _sent(rig, "PARAM_SET")


def test_restoring_puts_back_the_vehicles_plan_parameters_and_enable(rig):
    # After an upload over a vehicle holding a no-fly circle, FENCE_ALT_MAX 100, FENCE_TYPE 7
    # and FENCE_ENABLE 0, the restore uploads that plan again, sets both parameters back and
    # disables the fences, as they were.
    circle = (mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, 0, 1, 25.0,
              0.0, 0.0, 0.0, round(HOME[0] * 1e7) + 3000, round(HOME[1] * 1e7), 0.0)
    _connect(rig)
    rig.vehicle.upload_fence(SQUARE, 60.0)
    rig.tick()
    _vehicle_fence(rig, [circle])
    for seq in range(5):
        _request(rig, seq)
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED,
                                                  FENCE))
    rig.tick()
    for name, before, after, kind in [("FENCE_ALT_MAX", 100.0, 60.0, REAL32),
                                      ("FENCE_TYPE", 7.0, 5.0, INT8)]:
        _param(rig, name, before, kind)
        _param(rig, name, after, kind)
    _param(rig, "FENCE_ENABLE", 0.0, INT8)
    rig.peer.ack(mavlink.MAV_CMD_DO_FENCE_ENABLE)
    rig.tick()
    _param(rig, "FENCE_ACTION", 1.0, INT8)
    record = rig.vehicle.fence_upload
    assert record.uploaded
    rig.peer.drain()
    rig.peer.received.clear()

    handle = rig.vehicle.restore_fence()
    rig.tick()
    [count] = _sent(rig, "MISSION_COUNT")
    assert (count.count, count.mission_type) == (1, FENCE), "the vehicle's own plan"
    _request(rig, 0)
    [item] = _sent(rig, "MISSION_ITEM_INT")
    assert (item.frame, item.command, item.current, item.autocontinue, item.param1,
            item.param2, item.param3, item.param4, item.x, item.y, item.z) == circle
    rig.peer.send(rig.peer.mav.mission_ack_encode(255, 190, mavlink.MAV_MISSION_ACCEPTED,
                                                  FENCE))
    rig.tick()
    for name, before, kind in [("FENCE_ALT_MAX", 100.0, REAL32), ("FENCE_TYPE", 7.0, INT8)]:
        last = _sent(rig, "PARAM_SET")[-1]
        assert (last.param_id, last.param_value) == (name, before)
        _param(rig, name, before, kind)
    [disable] = rig.peer.commands(mavlink.MAV_CMD_DO_FENCE_ENABLE)
    assert disable.param1 == 0, "FENCE_ENABLE was 0: the fences go off again"
    rig.peer.ack(mavlink.MAV_CMD_DO_FENCE_ENABLE)
    rig.tick()
    assert handle.status is CommandStatus.ACCEPTED, handle.reason
    assert record.describe_restore() == (
        "the vehicle's geofence restored on the autopilot: its fence plan (1 zone), "
        "FENCE_ALT_MAX 100, FENCE_TYPE 7, fences disabled as FENCE_ENABLE")


def test_nothing_is_restored_without_an_accepted_upload(rig):
    _connect(rig)
    handle = rig.vehicle.restore_fence()
    assert (handle.status, handle.reason) == (CommandStatus.DENIED, "no geofence was uploaded")
