"""The embedded SITL with its PX4 personality: self-streaming telemetry, AUTO modes and the
OFFBOARD setpoint-stream rules."""

from __future__ import annotations

import math

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl
from sitl.copter.gcs import MiniGcs

OFFBOARD = 0x00060000
TAKEOFF = 0x02040000
LOITER = 0x03040000
LAND = 0x06040000
DT = 0.05


def connect(**kwargs) -> tuple[Sitl, MiniGcs]:
    sim = Sitl(autopilot="px4", **kwargs)
    link = MemoryLink()
    sim.attach(link.vehicle)
    return sim, MiniGcs(link.gcs)


def run(sim, gcs, seconds, until=None, each_step=None) -> bool:
    end = sim.time + seconds
    while sim.time < end - 1e-9:
        if each_step is not None:
            each_step()
        sim.step(DT)
        gcs.poll()
        if until is not None and until():
            return True
    return until is None


def mode(gcs) -> int:
    return gcs.last["HEARTBEAT"].custom_mode


def armed_after_settling(sim, gcs) -> None:
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.arm()
    run(sim, gcs, 0.1)
    assert sim.truth.armed


def test_streams_by_itself_and_idles_in_auto_loiter():
    sim, gcs = connect()
    run(sim, gcs, 10.0)
    hb = gcs.last["HEARTBEAT"]
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_PX4
    assert hb.custom_mode == LOITER
    rates = sim.settings.rates
    for name, hz in [
        ("ATTITUDE", rates.attitude),
        ("GLOBAL_POSITION_INT", rates.global_position_int),
        ("LOCAL_POSITION_NED", rates.local_position_ned),
        ("DISTANCE_SENSOR", rates.distance_sensor),
        ("SYS_STATUS", rates.sys_status),
        ("EXTENDED_SYS_STATE", rates.extended_sys_state),
        ("BATTERY_STATUS", rates.battery_status),
        ("HEARTBEAT", rates.heartbeat),
    ]:
        expected = 10.0 * min(hz, 1.0 / DT)  # at most one per step
        assert gcs.counts[name] == pytest.approx(expected, rel=0.1, abs=1.5), name
    # HOME_POSITION only once home is known (EKF settled), then at its rate.
    settled_for = 10.0 - sim.settings.arming_settle_time
    assert 1 + settled_for * rates.home_position - 1 <= gcs.counts["HOME_POSITION"]
    assert gcs.counts["HOME_POSITION"] <= 2 + settled_for * rates.home_position


def test_arming_refused_until_settled():
    sim, gcs = connect()
    gcs.arm()
    run(sim, gcs, 0.5)
    assert gcs.acks(mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == [
        mavlink.MAV_RESULT_TEMPORARILY_REJECTED
    ]
    assert gcs.texts()
    armed_after_settling(sim, gcs)


def test_takeoff_to_default_height_then_loiter():
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    gcs.takeoff(float("nan"))
    run(sim, gcs, 0.5)
    assert gcs.acks(mavlink.MAV_CMD_NAV_TAKEOFF) == [mavlink.MAV_RESULT_ACCEPTED]
    assert sim.truth.mode == "AUTO.TAKEOFF"
    assert mode(gcs) in (LOITER, TAKEOFF)  # the HEARTBEAT follows within a second
    run(sim, gcs, 1.0)
    assert mode(gcs) == TAKEOFF
    assert run(sim, gcs, 20.0, until=lambda: sim.truth.mode == "AUTO.LOITER")
    assert sim.truth.position[2] == pytest.approx(sim.settings.px4_takeoff_altitude, abs=0.35)


def test_takeoff_to_amsl_altitude():
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    gcs.takeoff(sim.settings.home.alt + 12.0)
    assert run(sim, gcs, 30.0, until=lambda: sim.truth.mode == "AUTO.LOITER")
    run(sim, gcs, 3.0)
    assert sim.truth.position[2] == pytest.approx(12.0, abs=0.2)


def test_offboard_refused_without_a_setpoint_stream():
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    gcs.set_mode(OFFBOARD, px4=True)
    run(sim, gcs, 1.5)
    assert gcs.acks(mavlink.MAV_CMD_DO_SET_MODE) == [mavlink.MAV_RESULT_ACCEPTED]
    assert mode(gcs) == LOITER
    assert any("Offboard" in t for t in gcs.texts())


def test_offboard_flies_the_stream_and_fails_over_to_hold_when_it_stops():
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    ticks = 0

    def stream():  # 5 Hz: every fourth 50 ms step
        nonlocal ticks
        if ticks % 4 == 0:
            gcs.goto_ned(5.0, 10.0, -8.0)
        ticks += 1

    run(sim, gcs, 1.5, each_step=stream)
    gcs.set_mode(OFFBOARD, px4=True)
    assert run(sim, gcs, 2.0, until=lambda: sim.truth.mode == "OFFBOARD", each_step=stream)
    run(sim, gcs, 20.0, each_step=stream)
    assert sim.truth.position == pytest.approx((10.0, 5.0, 8.0), abs=0.2)
    # The stream stops: after ~1 s PX4 leaves OFFBOARD. Its failsafe asks for Position,
    # which needs a pilot's sticks; without RC it falls back to Hold.
    stopped_at = sim.time
    assert run(sim, gcs, 5.0, until=lambda: sim.truth.mode == "AUTO.LOITER")
    assert sim.time - stopped_at == pytest.approx(sim.settings.offboard_loss_timeout, abs=0.15)
    run(sim, gcs, 1.5)
    assert mode(gcs) == LOITER
    held = sim.truth.position
    run(sim, gcs, 5.0)
    assert math.dist(held, sim.truth.position) < 0.1


def test_a_stale_setpoint_does_not_enable_offboard():
    # PX4's OffboardChecks: the latest setpoint must be younger than COM_OF_LOSS_T (1 s).
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    gcs.goto_ned(0.0, 0.0, -5.0)
    run(sim, gcs, 1.5)
    gcs.set_mode(OFFBOARD, px4=True)
    run(sim, gcs, 2.0)
    assert mode(gcs) == LOITER


def test_one_fresh_setpoint_enables_offboard():
    # MAVSDK sends its first setpoint and asks for OFFBOARD at once (offboard.start()); PX4
    # asks no rate of the stream, only that its latest setpoint be fresh.
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    gcs.goto_ned(0.0, 0.0, -5.0)
    run(sim, gcs, 0.1)
    gcs.set_mode(OFFBOARD, px4=True)
    run(sim, gcs, 0.2)
    assert sim.truth.mode == "OFFBOARD"


def test_land_then_disarm_two_seconds_after_touchdown():
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    gcs.takeoff(sim.settings.home.alt + 6.0)
    assert run(sim, gcs, 30.0, until=lambda: sim.truth.mode == "AUTO.LOITER")
    gcs.land()
    run(sim, gcs, 1.5)
    assert mode(gcs) == LAND
    assert run(sim, gcs, 60.0, until=lambda: sim.truth.landed)
    assert sim.truth.touchdown.speed == pytest.approx(sim.settings.px4_land_speed, abs=0.1)
    landed_at = sim.time
    assert run(sim, gcs, 5.0, until=lambda: not sim.truth.armed)
    assert sim.time - landed_at == pytest.approx(sim.settings.px4_land_disarm_delay, abs=0.1)


def test_disarms_ten_seconds_after_arming_without_takeoff():
    sim, gcs = connect()
    armed_after_settling(sim, gcs)
    armed_at = sim.time
    assert run(sim, gcs, 15.0, until=lambda: not sim.truth.armed)
    assert sim.time - armed_at == pytest.approx(sim.settings.disarm_delay, abs=0.2)


def test_takeoff_refused_when_disarmed():
    sim, gcs = connect()
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.takeoff(float("nan"))
    run(sim, gcs, 1.0)
    assert gcs.acks(mavlink.MAV_CMD_NAV_TAKEOFF) == [mavlink.MAV_RESULT_TEMPORARILY_REJECTED]
    assert sim.truth.landed and sim.truth.mode == "AUTO.LOITER"
