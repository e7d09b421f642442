"""Driver protocol behaviour against a scripted autopilot: what it sends, what it accepts,
how it tracks commands. Flights against the embedded SITL are in test_sitl_flight.py."""

import math

import pytest
from pydantic import ValidationError
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.vehicle import VehicleLinkSettings
from behaviors.ports import CommandStatus, LandedState

GUIDED, LAND, LOITER, STABILIZE = 4, 9, 5, 0
PX4 = mavlink.MAV_AUTOPILOT_PX4
PX4_LOITER = 0x03040000
PX4_OFFBOARD = 0x00060000


def test_sends_heartbeat_on_connect_and_every_second(rig):
    first = rig.peer.drain()
    assert [m.get_type() for m in first] == ["HEARTBEAT"]
    assert first[0].type == mavlink.MAV_TYPE_GCS
    rig.run(3.0)
    beats = [m for m in rig.peer.received if m.get_type() == "HEARTBEAT"]
    assert len(beats) == 4  # t=0, 1, 2, 3


def test_detects_autopilot_and_requests_streams(rig):
    assert rig.vehicle.state.link_lost
    rig.peer.heartbeat(custom_mode=STABILIZE)
    state = rig.tick()
    assert state.autopilot == "ardupilot"
    assert state.mode == "STABILIZE"
    assert not state.link_lost
    assert rig.vehicle.target_system == 1
    requests = rig.peer.commands(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL)
    assert requests, "the first stream request goes out at once"
    # One SET_MESSAGE_INTERVAL in flight at a time: the next goes when the ACK comes.
    for _ in range(10):
        rig.peer.ack(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL)
        rig.tick()
    asked = [int(m.param1) for m in rig.peer.commands(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL)]
    assert mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED in asked
    assert mavlink.MAVLINK_MSG_ID_HOME_POSITION in asked
    assert len(asked) == len(set(asked)) == len(VehicleLinkSettings().streams), "each once"


def test_telemetry_becomes_enu_state(rig):
    peer = rig.peer
    peer.heartbeat(custom_mode=GUIDED, armed=True)
    peer.send(
        peer.mav.home_position_encode(473977420, 85455940, 488000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)
    )
    peer.send(peer.mav.local_position_ned_encode(0, 10.0, 3.0, -20.0, 1.0, 2.0, -0.5))
    peer.send(peer.mav.attitude_encode(0, 0, 0, 0.0, 0, 0, 0))
    peer.send(peer.mav.sys_status_encode(0, 0, 0, 0, 12000, 0, 73, 0, 0, 0, 0, 0, 0))
    peer.send(peer.mav.gps_raw_int_encode(0, 3, 0, 0, 0, 0, 0, 0, 0, 10))
    peer.send(peer.mav.extended_sys_state_encode(0, mavlink.MAV_LANDED_STATE_IN_AIR))
    peer.send(
        peer.mav.distance_sensor_encode(
            0, 20, 4000, 1850, 0, 0, mavlink.MAV_SENSOR_ROTATION_PITCH_270, 0
        )
    )
    peer.text("EKF3 IMU0 is using GPS")
    s = rig.tick()
    assert s.position == (3.0, 10.0, 20.0)
    assert s.velocity == (2.0, 1.0, 0.5)
    assert math.isclose(s.yaw, math.pi / 2)
    assert s.armed and s.mode == "GUIDED"
    assert s.battery_percent == 73
    assert s.gps_fix == 3
    assert s.landed_state is LandedState.IN_AIR
    assert math.isclose(s.rangefinder_agl, 18.5)
    assert s.home == pytest.approx((47.397742, 8.545594, 488.0))
    assert s.last_status_text == "EKF3 IMU0 is using GPS"
    assert s.heartbeat_age == pytest.approx(0.0)


def test_ignores_other_systems_and_source_zero(make_rig):
    r = make_rig(target_system=2)
    other = type(r.peer)(r.link.vehicle, system=1)
    zero = type(r.peer)(r.link.vehicle, system=0, component=0)
    other.heartbeat(custom_mode=LAND)
    zero.heartbeat(custom_mode=LAND)
    assert r.tick().link_lost, "system 1 and 0/0 are not our vehicle"
    mine = type(r.peer)(r.link.vehicle, system=2)
    mine.heartbeat(custom_mode=GUIDED)
    other.send(other.mav.local_position_ned_encode(0, 50.0, 50.0, -50.0, 0, 0, 0))
    s = r.tick()
    assert s.mode == "GUIDED" and not s.link_lost
    assert s.position is None
    assert r.vehicle.stats.ignored == 3


def test_ground_station_heartbeat_is_not_a_vehicle(rig):
    rig.peer.send(
        rig.peer.mav.heartbeat_encode(
            mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, mavlink.MAV_STATE_ACTIVE
        )
    )
    assert rig.tick().link_lost
    assert rig.vehicle.target_system is None


def test_corrupt_bytes_are_skipped_and_counted(rig):
    peer = rig.peer
    peer.heartbeat(custom_mode=GUIDED)
    rig.tick()
    good = peer.mav.local_position_ned_encode(0, 1.0, 2.0, -3.0, 0, 0, 0).pack(peer.mav)
    broken = bytearray(
        peer.mav.local_position_ned_encode(0, 9.0, 9.0, -9.0, 0, 0, 0).pack(peer.mav)
    )
    broken[12] ^= 0xFF  # payload byte: the CRC no longer matches
    rig.link.vehicle.write(b"\x00\x01garbage\xff" + bytes(broken) + good)
    s = rig.tick()
    assert s.position == (2.0, 1.0, 3.0)
    stats = rig.vehicle.stats
    assert stats.corrupt_packets >= 2 and stats.corrupt_bytes >= 10 + len(broken)


def test_flood_is_decoded_in_bounded_batches(make_rig):
    r = make_rig(settings=VehicleLinkSettings(max_messages_per_poll=500))
    r.peer.heartbeat(custom_mode=GUIDED)
    r.tick()
    for i in range(10_000):
        r.peer.send(r.peer.mav.local_position_ned_encode(0, float(i), 0, 0, 0, 0, 0), flush=False)
    r.peer.flush()
    before = r.vehicle.stats.messages
    s = r.tick()
    assert r.vehicle.stats.messages - before == 500
    assert s.position == (0.0, 499.0, 0.0)
    for _ in range(19):
        s = r.tick()
    assert s.position == (0.0, 9999.0, -0.0)


def test_arm_denied_carries_prearm_text(rig):
    rig.peer.heartbeat(custom_mode=STABILIZE)
    rig.tick()
    handle = rig.vehicle.arm()
    assert handle.status is CommandStatus.PENDING
    rig.peer.drain()
    rig.peer.text("PreArm: Need Position Estimate")
    rig.peer.ack(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_RESULT_FAILED)
    rig.tick()
    assert handle.status is CommandStatus.PENDING, "a text may still follow the ACK"
    rig.run(0.5)
    assert handle.status is CommandStatus.DENIED
    assert handle.reason == (
        "PreArm: Need Position Estimate (MAV_CMD_COMPONENT_ARM_DISARM: MAV_RESULT_FAILED)"
    )


def test_a_refusal_carries_the_text_sent_just_after_the_ack(rig):
    # ArduPilot: COMMAND_ACK FAILED, then "Arm: Need Position Estimate" in the same instant.
    rig.peer.heartbeat(custom_mode=GUIDED)
    rig.peer.text("PreArm: Throttle below failsafe")  # an older check, not the reason now
    rig.tick()
    handle = rig.vehicle.arm()
    rig.tick()
    rig.peer.ack(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_RESULT_FAILED)
    rig.tick()
    rig.peer.text("Arm: Need Position Estimate")
    rig.tick()
    assert handle.status is CommandStatus.DENIED
    assert handle.reason == (
        "Arm: Need Position Estimate (MAV_CMD_COMPONENT_ARM_DISARM: MAV_RESULT_FAILED)"
    )


def test_a_mode_refusal_waits_briefly_for_its_text_then_ends_without_one(rig):
    rig.peer.heartbeat(custom_mode=STABILIZE)
    rig.tick()
    explained = rig.vehicle.set_mode("LOITER")
    rig.tick()
    rig.peer.ack(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_RESULT_DENIED)
    rig.peer.send(
        rig.peer.mav.statustext_encode(mavlink.MAV_SEVERITY_INFO, b"EKF3 IMU0 is using GPS")
    )
    rig.peer.send(
        rig.peer.mav.statustext_encode(mavlink.MAV_SEVERITY_WARNING, b"Mode change failed")
    )
    rig.tick()
    assert explained.status is CommandStatus.DENIED
    assert explained.reason == "Mode change failed (MAV_CMD_DO_SET_MODE: MAV_RESULT_DENIED)"
    bare = rig.vehicle.set_mode("RTL")
    rig.tick()
    rig.peer.ack(mavlink.MAV_CMD_DO_SET_MODE, mavlink.MAV_RESULT_DENIED)
    rig.tick()
    assert bare.status is CommandStatus.PENDING
    rig.run(0.5)
    assert bare.status is CommandStatus.DENIED
    assert bare.reason == "MAV_CMD_DO_SET_MODE: MAV_RESULT_DENIED"


def test_command_is_resent_with_confirmation_then_times_out(make_rig):
    r = make_rig(
        settings=VehicleLinkSettings(ack_timeout=0.5, command_attempts=3, link_timeout=100)
    )
    r.peer.heartbeat(custom_mode=STABILIZE)
    r.tick()
    handle = r.vehicle.set_mode("LOITER")
    r.run(1.4)
    sent = r.peer.commands(mavlink.MAV_CMD_DO_SET_MODE)
    assert [m.confirmation for m in sent] == [0, 1, 2]
    assert handle.status is CommandStatus.PENDING
    r.run(0.2)
    assert handle.status is CommandStatus.TIMED_OUT
    assert "COMMAND_ACK" in handle.reason


def test_mode_change_is_confirmed_by_heartbeat(rig):
    rig.peer.heartbeat(custom_mode=STABILIZE)
    rig.tick()
    handle = rig.vehicle.set_mode("AUTO.LOITER")  # PX4's word, ArduPilot's LOITER
    rig.tick()
    assert [int(m.param2) for m in rig.peer.commands(mavlink.MAV_CMD_DO_SET_MODE)] == [LOITER]
    rig.peer.ack(mavlink.MAV_CMD_DO_SET_MODE)
    rig.tick()
    assert handle.status is CommandStatus.IN_PROGRESS, "ACK alone does not prove the mode"
    rig.peer.heartbeat(custom_mode=LOITER)
    rig.tick()
    assert handle.status is CommandStatus.ACCEPTED
    assert rig.vehicle.state.mode == "LOITER"


def test_px4_offboard_acked_but_not_entered_is_denied(rig):
    rig.peer.heartbeat(custom_mode=PX4_LOITER, autopilot=PX4)
    rig.peer.send(rig.peer.mav.local_position_ned_encode(0, 0, 0, -5.0, 0, 0, 0))
    assert rig.tick().mode == "AUTO.LOITER"
    handle = rig.vehicle.goto(10.0, 0.0, 5.0)
    rig.run(0.6, heartbeat=dict(custom_mode=PX4_LOITER, autopilot=PX4))
    setpoints = [m for m in rig.peer.received if m.get_type() == "SET_POSITION_TARGET_LOCAL_NED"]
    mode_cmds = rig.peer.commands(mavlink.MAV_CMD_DO_SET_MODE)
    assert mode_cmds and len(setpoints) >= 10, "setpoints stream before OFFBOARD is asked"
    first_mode_cmd = rig.peer.received.index(mode_cmds[0])
    assert rig.peer.received.index(setpoints[9]) < first_mode_cmd
    sp = setpoints[-1]
    assert (sp.coordinate_frame, sp.type_mask) == (mavlink.MAV_FRAME_LOCAL_NED, 0x0DF8)
    assert (sp.x, sp.y, sp.z) == (0.0, 10.0, -5.0)
    assert (int(mode_cmds[0].param2), int(mode_cmds[0].param3)) == (6, 0)
    rig.peer.ack(mavlink.MAV_CMD_DO_SET_MODE)
    rig.run(4.0, heartbeat=dict(custom_mode=PX4_LOITER, autopilot=PX4))
    assert handle.status is CommandStatus.DENIED
    assert "AUTO.LOITER" in handle.reason


def test_link_loss_fails_commands_fast(make_rig):
    r = make_rig(link_timeout=2.0)
    r.run(3.0, heartbeat=dict(custom_mode=GUIDED))
    pending = r.vehicle.set_mode("LAND")
    assert not r.vehicle.state.link_lost
    r.run(2.5)  # the autopilot falls silent
    assert r.vehicle.state.link_lost
    assert pending.status is CommandStatus.TIMED_OUT and "link lost" in pending.reason
    late = r.vehicle.land()
    assert late.status is CommandStatus.TIMED_OUT
    r.run(1.0, heartbeat=dict(custom_mode=GUIDED))
    assert not r.vehicle.state.link_lost
    assert r.vehicle.stats.links_lost == 1


def test_operator_mode_change_is_reported_and_stops_the_setpoint_stream(rig):
    rig.peer.heartbeat(custom_mode=GUIDED, armed=True)
    rig.peer.send(rig.peer.mav.local_position_ned_encode(0, 0, 0, -10.0, 0, 0, 0))
    rig.tick()
    handle = rig.vehicle.goto(20.0, 0.0, 10.0)
    assert handle.status is CommandStatus.ACCEPTED, "already in GUIDED"
    rig.run(1.0)

    def count():
        return sum(m.get_type() == "SET_POSITION_TARGET_LOCAL_NED" for m in rig.peer.received)

    streamed = count()
    assert streamed >= 4
    rig.peer.heartbeat(custom_mode=LOITER, armed=True)  # someone else switched to LOITER
    rig.tick()
    after = count()
    rig.run(2.0)
    assert count() == after
    change = rig.vehicle.mode_changes[-1]
    assert (change.old, change.new, change.requested) == ("GUIDED", "LOITER", False)


def test_unknown_mode_is_denied(rig):
    rig.peer.heartbeat(custom_mode=GUIDED)
    rig.tick()
    handle = rig.vehicle.set_mode("WARP_DRIVE")
    assert handle.status is CommandStatus.DENIED and "WARP_DRIVE" in handle.reason


def test_px4_takes_either_familys_mode_names(rig):
    rig.peer.heartbeat(custom_mode=PX4_LOITER, autopilot=PX4)
    rig.tick()
    rig.vehicle.set_mode("RTL")  # ArduPilot's word for AUTO.RTL
    rig.tick()
    sent = rig.peer.commands(mavlink.MAV_CMD_DO_SET_MODE)[-1]
    assert (sent.param1, sent.param2, sent.param3) == (1, 4, 5)
    rig.peer.ack(mavlink.MAV_CMD_DO_SET_MODE)
    rig.peer.heartbeat(custom_mode=0x05040000, autopilot=PX4)
    assert rig.tick().mode == "AUTO.RTL"


def test_stream_settings_name_real_messages():
    with pytest.raises(ValidationError, match="streams"):
        VehicleLinkSettings(streams={"LOCAL_POSITION_NEDD": 10.0})
    with pytest.raises(ValidationError, match="link_timeout"):
        VehicleLinkSettings(link_timeout=0)


def test_packets_split_across_reads_are_reassembled(rig):
    peer = rig.peer
    peer.heartbeat(custom_mode=GUIDED)
    rig.tick()
    stream = b"".join(
        peer.mav.local_position_ned_encode(0, float(i), 0, 0, 0, 0, 0).pack(peer.mav)
        for i in range(3000)
    )
    before = rig.vehicle.stats.messages
    cut = 0
    while cut < len(stream):  # 50 bytes per read: most packets arrive in two pieces
        rig.link.vehicle.write(stream[cut : cut + 50])
        cut += 50
        state = rig.tick(0.001)
    assert rig.vehicle.stats.messages - before == 3000
    assert rig.vehicle.stats.corrupt_bytes == 0
    assert state.position == (0.0, 2999.0, -0.0)


def test_land_supersedes_a_goto_still_waiting_for_offboard(rig):
    rig.peer.heartbeat(custom_mode=PX4_LOITER, autopilot=PX4)
    rig.peer.send(rig.peer.mav.local_position_ned_encode(0, 0, 0, -5.0, 0, 0, 0))
    rig.tick()
    goto = rig.vehicle.goto(10.0, 0.0, 5.0)
    rig.run(0.2)
    land = rig.vehicle.land()
    assert goto.status is CommandStatus.DENIED and "superseded by land" in goto.reason
    streamed = sum(m.get_type() == "SET_POSITION_TARGET_LOCAL_NED" for m in rig.peer.received)
    rig.run(1.0)
    assert streamed == sum(
        m.get_type() == "SET_POSITION_TARGET_LOCAL_NED" for m in rig.peer.received
    ), "the stream stops"
    assert not rig.peer.commands(mavlink.MAV_CMD_DO_SET_MODE), "OFFBOARD is never asked for"
    # Only NAV_LAND goes out (re-sent once: this peer never answers).
    assert {m.command for m in rig.peer.commands() if m.command != 511} == {
        mavlink.MAV_CMD_NAV_LAND
    }
    assert land.status is CommandStatus.PENDING


def test_a_stale_prearm_text_is_not_the_reason(make_rig):
    r = make_rig(link_timeout=100.0)
    r.peer.heartbeat(custom_mode=STABILIZE)
    r.peer.text("PreArm: Need Position Estimate")
    r.tick()
    r.run(40.0, heartbeat=dict(custom_mode=STABILIZE))
    handle = r.vehicle.arm()
    r.peer.ack(mavlink.MAV_CMD_COMPONENT_ARM_DISARM, mavlink.MAV_RESULT_DENIED)
    r.run(0.6)
    assert handle.status is CommandStatus.DENIED
    assert handle.reason == "MAV_CMD_COMPONENT_ARM_DISARM: MAV_RESULT_DENIED"


def test_position_estimate_follows_the_ekf_where_the_autopilot_reports_it(rig):
    peer = rig.peer
    peer.heartbeat(custom_mode=STABILIZE)
    peer.send(peer.mav.local_position_ned_encode(0, 0, 0, 0, 0, 0, 0))
    peer.send(
        peer.mav.home_position_encode(473977420, 85455940, 488000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)
    )
    peer.send(peer.mav.ekf_status_report_encode(mavlink.EKF_ATTITUDE, 0, 0, 0, 0, 0))
    assert not rig.tick().position_estimate, "the EKF says no, whatever else is known"
    peer.send(peer.mav.ekf_status_report_encode(mavlink.EKF_PRED_POS_HORIZ_ABS, 0, 0, 0, 0, 0))
    assert rig.tick().position_estimate, "disarmed, a predicted position is enough"
    peer.heartbeat(custom_mode=GUIDED, armed=True)
    assert not rig.tick().position_estimate, "armed, it must be a real one"
    peer.send(peer.mav.ekf_status_report_encode(mavlink.EKF_POS_HORIZ_ABS, 0, 0, 0, 0, 0))
    assert rig.tick().position_estimate


def test_without_ekf_reports_a_home_and_a_position_make_the_estimate(rig):
    peer = rig.peer
    peer.heartbeat(custom_mode=PX4_LOITER, autopilot=PX4)
    peer.send(peer.mav.local_position_ned_encode(0, 0, 0, 0, 0, 0, 0))
    assert not rig.tick().position_estimate, "no home yet"
    peer.send(
        peer.mav.home_position_encode(473977420, 85455940, 488000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)
    )
    assert rig.tick().position_estimate



def test_px4_is_ready_to_arm_only_when_its_prearm_health_bit_says_so(rig):
    """PX4 sets MAV_SYS_STATUS_PREARM_CHECK in health alone (never in present) once it can
    arm; a GPS fix, a position and a home come seconds earlier, while it still refuses
    ("Preflight Fail: no heading reference")."""
    peer = rig.peer
    prearm = mavlink.MAV_SYS_STATUS_PREARM_CHECK
    sensors = 0x0300402F  # what PX4 v1.17 SIH reports present once its health report is up
    peer.heartbeat(custom_mode=PX4_LOITER, autopilot=PX4)
    peer.send(peer.mav.gps_raw_int_encode(0, 3, 473977420, 85455940, 488000, 70, 110, 0, 0, 10))
    peer.send(peer.mav.local_position_ned_encode(0, 0, 0, 0, 0, 0, 0))
    peer.send(
        peer.mav.home_position_encode(473977420, 85455940, 488000, 0, 0, 0, [1, 0, 0, 0], 0, 0, 0)
    )
    peer.send(peer.mav.sys_status_encode(sensors, sensors, sensors, 0, 16200, -1, 99, 0, 0, 0,
                                         0, 0, 0))  # fmt: skip
    s = rig.tick()
    assert s.gps_fix == 3 and s.position is not None and s.home is not None
    assert not s.prearm_ok, "PX4 has not passed its checks yet"
    peer.send(peer.mav.sys_status_encode(sensors, sensors, sensors | prearm, 0, 16200, -1, 99,
                                         0, 0, 0, 0, 0, 0))  # fmt: skip
    assert rig.tick().prearm_ok
    peer.send(peer.mav.sys_status_encode(sensors, sensors, sensors, 0, 16200, -1, 99, 0, 0, 0,
                                         0, 0, 0))  # fmt: skip
    assert not rig.tick().prearm_ok, "and not once it says it no longer can"

def test_link_statistics_count_gaps_and_time_lost(make_rig):
    r = make_rig(link_timeout=2.0)
    r.run(3.0, heartbeat=dict(custom_mode=GUIDED))  # heartbeats at 0.05, 1.05, 2.05 s
    r.run(5.0)  # silent: lost once 2 s have passed (at 4.1 s)
    r.run(2.0, heartbeat=dict(custom_mode=GUIDED))  # back at 8.05 s
    stats = r.vehicle.stats
    assert stats.first_heartbeat == pytest.approx(0.05)
    assert stats.links_lost == 1
    assert r.vehicle.time_lost() == pytest.approx(3.95)
    assert r.vehicle.longest_heartbeat_gap() == pytest.approx(6.0)
    assert stats.heartbeats == 5


def test_the_autopilots_time_stamps_feed_the_clock(make_rig):
    seen = []
    r = make_rig(on_vehicle_time=seen.append)
    r.peer.heartbeat(custom_mode=GUIDED)
    r.tick()
    for ms in (1000, 1100, 1050):  # one batch: the newest counts
        r.peer.send(r.peer.mav.attitude_encode(ms, 0, 0, 0, 0, 0, 0), flush=False)
    r.peer.flush()
    r.tick()
    other = type(r.peer)(r.link.vehicle, system=1, component=154)  # a gimbal of the vehicle
    other.send(other.mav.attitude_encode(99000, 0, 0, 0, 0, 0, 0))
    r.tick()
    assert seen == [1.1]
