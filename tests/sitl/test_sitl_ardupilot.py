"""The embedded SITL with its ArduPilot Copter personality, driven over the in-memory link
by a plain pymavlink client (everything crosses as MAVLink bytes)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl, SitlSettings
from sitl.copter.gcs import MiniGcs

GUIDED, LAND, LOITER, RTL = 4, 9, 5, 6
DT = 0.05


def connect(**kwargs) -> tuple[Sitl, MiniGcs]:
    sim = Sitl(**kwargs)
    link = MemoryLink()
    sim.attach(link.vehicle)
    return sim, MiniGcs(link.gcs)


def run(sim: Sitl, gcs: MiniGcs, seconds: float, until=None) -> bool:
    """Step the SITL for up to ``seconds`` (sim time); True as soon as ``until()`` holds."""
    end = sim.time + seconds
    while sim.time < end - 1e-9:
        sim.step(DT)
        gcs.poll()
        if until is not None and until():
            return True
    return until is None


def airborne(sim, gcs, altitude=10.0) -> None:
    """Settle, switch to GUIDED, arm and take off to ``altitude``."""
    gcs.heartbeat()
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.set_mode(GUIDED)
    gcs.arm()
    gcs.takeoff(altitude)
    assert run(sim, gcs, 30, until=lambda: sim.truth.position[2] > altitude - 0.1)


class Ramp:
    """Terrain: a plane rising ``grade`` m per m toward east, ``offset`` m high at x = 0."""

    def __init__(self, grade: float, offset: float = 0.0) -> None:
        self.grade, self.offset = grade, offset

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return self.offset + self.grade * x


def test_silent_until_spoken_to_then_only_heartbeat_and_home():
    sim, gcs = connect()
    run(sim, gcs, 2.0)
    assert gcs.received == []
    gcs.heartbeat()
    run(sim, gcs, 10.0)
    assert set(gcs.counts) == {"HEARTBEAT", "HOME_POSITION"}
    assert gcs.counts["HOME_POSITION"] == 1
    assert 9 <= gcs.counts["HEARTBEAT"] <= 11
    hb = gcs.last["HEARTBEAT"]
    assert hb.autopilot == mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA
    assert hb.type == mavlink.MAV_TYPE_QUADROTOR


def test_every_interval_request_is_acked_and_streams_at_that_rate():
    sim, gcs = connect()
    gcs.heartbeat()
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, 10)
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 2)
    gcs.set_interval(4242, 5)  # no such message: FAILED and said why, as ArduPilot does
    run(sim, gcs, 10.0)
    assert gcs.acks(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL) == [mavlink.MAV_RESULT_ACCEPTED] * 2 + [
        mavlink.MAV_RESULT_FAILED
    ]
    assert "No ap_message for mavlink id (4242)" in gcs.texts()
    assert 98 <= gcs.counts["GLOBAL_POSITION_INT"] <= 102
    assert 19 <= gcs.counts["EXTENDED_SYS_STATE"] <= 21
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT, -1)
    run(sim, gcs, 0.2)
    before = gcs.counts["GLOBAL_POSITION_INT"]
    run(sim, gcs, 3.0)
    assert gcs.counts["GLOBAL_POSITION_INT"] == before


def test_arming_denied_with_prearm_text_until_settled():
    sim, gcs = connect()
    gcs.heartbeat()
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_SYS_STATUS, 2)
    gcs.arm()
    run(sim, gcs, 0.5)
    assert gcs.acks(mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == [mavlink.MAV_RESULT_FAILED]
    assert any(t.startswith("PreArm:") for t in gcs.texts())
    assert not gcs.last["SYS_STATUS"].onboard_control_sensors_health & 0x10000000
    assert not sim.truth.armed
    run(sim, gcs, sim.settings.arming_settle_time)
    assert gcs.last["SYS_STATUS"].onboard_control_sensors_health & 0x10000000
    gcs.arm()
    run(sim, gcs, 1.1)  # one heartbeat period
    assert gcs.acks(mavlink.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == mavlink.MAV_RESULT_ACCEPTED
    assert sim.truth.armed
    assert gcs.last["HEARTBEAT"].base_mode & mavlink.MAV_MODE_FLAG_SAFETY_ARMED
    assert gcs.texts()[-1] == "Arming motors"  # what ArduPilot's SITL builds say


def test_guided_refused_until_the_position_estimate_settles():
    sim, gcs = connect()
    gcs.heartbeat()
    gcs.set_mode(GUIDED)
    run(sim, gcs, 1.5)
    assert gcs.acks(mavlink.MAV_CMD_DO_SET_MODE) == [mavlink.MAV_RESULT_FAILED]
    assert gcs.last["HEARTBEAT"].custom_mode == 0  # still STABILIZE
    run(sim, gcs, sim.settings.arming_settle_time)
    gcs.set_mode(GUIDED)
    run(sim, gcs, 1.5)
    assert gcs.acks(mavlink.MAV_CMD_DO_SET_MODE)[-1] == mavlink.MAV_RESULT_ACCEPTED
    assert gcs.last["HEARTBEAT"].custom_mode == GUIDED


def test_settings_name_the_bad_field():
    with pytest.raises(ValidationError, match="max_horizontal_speed"):
        SitlSettings(max_horizontal_speed=-1)
    with pytest.raises(ValidationError, match="rangefinder_min"):
        SitlSettings(rangefinder_min=50, rangefinder_max=40)
    with pytest.raises(ValueError, match="autopilot"):
        Sitl(autopilot="inav")


def test_takeoff_refused_when_disarmed_or_not_guided():
    sim, gcs = connect()
    gcs.heartbeat()
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.set_mode(GUIDED)
    gcs.takeoff(10)  # disarmed
    gcs.set_mode(LOITER)
    gcs.arm()
    gcs.takeoff(10)  # armed, not GUIDED
    run(sim, gcs, 2.0)
    assert gcs.acks(mavlink.MAV_CMD_NAV_TAKEOFF) == [mavlink.MAV_RESULT_FAILED] * 2
    assert sim.truth.landed


def test_guided_takeoff_reaches_altitude_and_reports_in_air():
    sim, gcs = connect()
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 5)
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED, 5)
    airborne(sim, gcs, 10.0)
    assert gcs.acks(mavlink.MAV_CMD_NAV_TAKEOFF) == [mavlink.MAV_RESULT_ACCEPTED]
    run(sim, gcs, 5.0)
    assert sim.truth.position[2] == pytest.approx(10.0, abs=0.2)
    assert gcs.last["LOCAL_POSITION_NED"].z == pytest.approx(-10.0, abs=0.2)
    assert gcs.last["EXTENDED_SYS_STATE"].landed_state == mavlink.MAV_LANDED_STATE_IN_AIR
    assert gcs.last["HEARTBEAT"].custom_mode == GUIDED


def test_position_target_reached_within_speed_limit():
    sim, gcs = connect()
    airborne(sim, gcs)
    gcs.goto_ned(40.0, -30.0, -15.0)  # 40 m north, 30 m west, 15 m up
    top_speed = 0.0

    def there():
        nonlocal top_speed
        vx, vy, _ = sim.truth.velocity
        top_speed = max(top_speed, math.hypot(vx, vy))
        return False

    run(sim, gcs, 40.0, until=there)
    x, y, z = sim.truth.position
    assert (x, y, z) == pytest.approx((-30.0, 40.0, 15.0), abs=0.3)
    assert top_speed <= sim.settings.max_horizontal_speed + 1e-6
    assert top_speed > 0.5 * sim.settings.max_horizontal_speed


def hover_in_wind(gust_sigma: float, seconds: float):
    """A simulator hovering at ENU (0, 20, 10) after ``seconds`` in a 6 m/s east wind."""
    settings = SitlSettings(wind={"speed": 6.0, "direction": 90.0, "gust_sigma": gust_sigma})
    sim, gcs = connect(settings=settings, seed=3)
    airborne(sim, gcs)
    gcs.goto_ned(20.0, 0.0, -10.0)
    run(sim, gcs, seconds)
    return sim, gcs


def test_hover_in_a_steady_wind_holds_its_point():
    # The velocity loop's integrator takes up the wind's push, as ArduPilot's does: a
    # hover (and so a landing) holds its point instead of sitting downwind of it.
    sim, _ = hover_in_wind(gust_sigma=0.0, seconds=40.0)
    x, y, z = sim.truth.position
    assert math.hypot(x - 0.0, y - 20.0) < 0.05
    assert abs(z - 10.0) < 0.1


def test_gusts_move_a_hover_only_a_little():
    sim, gcs = hover_in_wind(gust_sigma=1.0, seconds=30.0)
    errors = []
    for _ in range(20):
        run(sim, gcs, 0.5)
        x, y, _z = sim.truth.position
        errors.append(math.hypot(x - 0.0, y - 20.0))
    assert max(errors) < 0.5
    assert sum(errors) / len(errors) < 0.3


def test_velocity_target_then_stop_after_timeout():
    sim, gcs = connect()
    airborne(sim, gcs)
    gcs.velocity_ned(2.0, 0.0, 0.0)
    run(sim, gcs, 2.5)
    assert sim.truth.velocity[1] == pytest.approx(2.0, abs=0.2)
    run(sim, gcs, 3.0)  # not refreshed for > 3 s: ArduPilot stops
    assert math.hypot(*sim.truth.velocity[:2]) < 0.2


def test_land_on_raised_slope_touches_down_at_terrain_height_and_disarms():
    terrain = Ramp(grade=0.1, offset=0.0)  # ~5.7 degrees
    sim, gcs = connect(terrain=terrain)
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE, 5)
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR, 5)
    airborne(sim, gcs, 20.0)
    gcs.goto_ned(0.0, 50.0, -20.0)  # 50 m east, where the ground is 5 m high
    run(sim, gcs, 20.0)
    assert gcs.last["DISTANCE_SENSOR"].current_distance == pytest.approx(1500, abs=30)
    gcs.set_mode(LAND)
    saw_landing = run(sim, gcs, 60.0, until=lambda: gcs.last["EXTENDED_SYS_STATE"].landed_state
                      == mavlink.MAV_LANDED_STATE_LANDING)
    assert saw_landing
    assert run(sim, gcs, 60.0, until=lambda: sim.truth.landed)
    truth = sim.truth
    touchdown = truth.touchdown
    assert touchdown.z == pytest.approx(terrain.height(touchdown.x, touchdown.y), abs=1e-6)
    assert touchdown.z == pytest.approx(5.0, abs=0.1)
    assert touchdown.speed == pytest.approx(sim.settings.land_speed, abs=0.1)
    assert not truth.crashed
    assert truth.armed  # it disarms about a second later
    landed_at = sim.time
    assert run(sim, gcs, 5.0, until=lambda: not sim.truth.armed)
    assert sim.time - landed_at == pytest.approx(sim.settings.land_disarm_delay, abs=0.1)
    assert gcs.last["EXTENDED_SYS_STATE"].landed_state == mavlink.MAV_LANDED_STATE_ON_GROUND


def test_landing_on_a_steep_slope_is_a_crash():
    sim, gcs = connect(terrain=Ramp(grade=0.6))  # ~31 degrees
    airborne(sim, gcs, 15.0)
    gcs.set_mode(LAND)
    assert run(sim, gcs, 60.0, until=lambda: sim.truth.landed)
    truth = sim.truth
    assert truth.crashed
    assert "slope" in truth.crash_reason
    assert truth.touchdown_slope_deg == pytest.approx(math.degrees(math.atan(0.6)), abs=0.5)
    assert not truth.armed
    assert any(t.startswith("Crash") for t in gcs.texts())


def test_forced_disarm_in_the_air_falls_and_crashes_hard():
    sim, gcs = connect()
    airborne(sim, gcs, 10.0)
    gcs.disarm()  # refused in the air without force
    run(sim, gcs, 0.5)
    assert sim.truth.armed
    assert gcs.acks(mavlink.MAV_CMD_COMPONENT_ARM_DISARM)[-1] == mavlink.MAV_RESULT_FAILED
    gcs.disarm(force=True)
    assert run(sim, gcs, 10.0, until=lambda: sim.truth.landed)
    assert sim.truth.crashed
    assert "hard landing" in sim.truth.crash_reason
    assert sim.truth.touchdown.speed > sim.settings.crash_speed


def test_flying_into_rising_terrain_is_a_crash():
    sim, gcs = connect(terrain=Ramp(grade=0.15))
    airborne(sim, gcs, 5.0)
    gcs.goto_ned(0.0, 200.0, -5.0)  # level flight east, into the slope
    assert run(sim, gcs, 60.0, until=lambda: sim.truth.landed)
    truth = sim.truth
    assert truth.crashed and "sideways" in truth.crash_reason
    assert truth.touchdown.x == pytest.approx(5.0 / 0.15, abs=1.0)


def test_guided_targets_are_ignored_in_land():
    sim, gcs = connect()
    airborne(sim, gcs, 10.0)
    gcs.set_mode(LAND)
    run(sim, gcs, 1.0)
    gcs.goto_ned(30.0, 30.0, -10.0)
    run(sim, gcs, 5.0)
    x, y, _ = sim.truth.position
    assert math.hypot(x, y) < 0.1
    assert sim.truth.mode == "LAND"


def test_armed_in_guided_without_takeoff_disarms_after_ten_seconds():
    sim, gcs = connect()
    gcs.heartbeat()
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.set_mode(GUIDED)
    gcs.arm()
    run(sim, gcs, 0.1)
    armed_at = sim.time
    assert sim.truth.armed
    assert run(sim, gcs, 15.0, until=lambda: not sim.truth.armed)
    assert sim.time - armed_at == pytest.approx(sim.settings.disarm_delay, abs=0.2)


def test_rtl_climbs_returns_and_lands_at_home():
    sim, gcs = connect()
    airborne(sim, gcs, 5.0)
    gcs.goto_ned(30.0, 0.0, -5.0)
    run(sim, gcs, 15.0)
    gcs.set_mode(RTL)
    peak = 0.0

    def done():
        nonlocal peak
        peak = max(peak, sim.truth.position[2])
        return not sim.truth.armed

    assert run(sim, gcs, 120.0, until=done)
    assert peak == pytest.approx(sim.settings.rtl_altitude, abs=0.3)
    x, y, z = sim.truth.position
    assert math.hypot(x, y) < 1.0 and z == 0.0
    assert not sim.truth.crashed


def test_battery_drains_faster_when_climbing():
    sim, gcs = connect()
    airborne(sim, gcs, 3.0)
    run(sim, gcs, 5.0)
    start = sim.truth.battery_percent
    run(sim, gcs, 10.0)
    hover = start - sim.truth.battery_percent
    gcs.goto_ned(0.0, 0.0, -100.0)
    run(sim, gcs, 2.0)
    start = sim.truth.battery_percent
    run(sim, gcs, 10.0)
    climbing = start - sim.truth.battery_percent
    assert hover > 0
    assert climbing > hover * 1.2


def test_same_seed_same_flight_in_gusts():
    def flight(seed):
        settings = SitlSettings(wind={"speed": 3.0, "gust_sigma": 2.0})
        sim, gcs = connect(settings=settings, seed=seed)
        airborne(sim, gcs, 10.0)
        gcs.goto_ned(10.0, 10.0, -10.0)
        run(sim, gcs, 10.0)
        return sim.truth.position

    assert flight(1) == flight(1)
    assert flight(1) != flight(2)


def test_legacy_stream_requests_and_one_shot_messages():
    sim, gcs = connect()
    gcs.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_POSITION, 5, 1)
    gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    gcs.command(mavlink.MAV_CMD_GET_MESSAGE_INTERVAL, mavlink.MAVLINK_MSG_ID_ATTITUDE)
    gcs.command(mavlink.MAV_CMD_DO_SET_SERVO, 9, 1500)  # not simulated
    run(sim, gcs, 4.0)
    assert 18 <= gcs.counts["GLOBAL_POSITION_INT"] <= 21
    assert 18 <= gcs.counts["LOCAL_POSITION_NED"] <= 21
    assert "ATTITUDE" not in gcs.counts
    assert gcs.last["AUTOPILOT_VERSION"].capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2
    assert gcs.last["MESSAGE_INTERVAL"].interval_us == -1  # available, not streaming
    assert gcs.acks(mavlink.MAV_CMD_DO_SET_SERVO) == [mavlink.MAV_RESULT_UNSUPPORTED]


def test_commands_for_another_system_are_ignored():
    sim, gcs = connect()
    gcs.heartbeat()
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)
    gcs.target = (7, 1)
    gcs.arm()
    run(sim, gcs, 1.0)
    assert gcs.acks(mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == []
    assert not sim.truth.armed


def test_between_prearm_and_position_estimate_it_arms_in_stabilize_only():
    sim, gcs = connect(settings=SitlSettings(arming_settle_time=2.0, position_settle_time=6.0))
    gcs.heartbeat()
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT, 2)
    run(sim, gcs, 3.0)
    flags = gcs.last["EKF_STATUS_REPORT"].flags
    assert flags & mavlink.EKF_CONST_POS_MODE and not flags & mavlink.EKF_POS_HORIZ_ABS
    assert "HOME_POSITION" not in gcs.last
    gcs.set_mode(GUIDED)
    run(sim, gcs, 0.1)
    assert gcs.acks(mavlink.MAV_CMD_DO_SET_MODE) == [mavlink.MAV_RESULT_FAILED]
    assert "Mode change to GUIDED failed: requires position" in gcs.texts()
    gcs.arm()  # in STABILIZE: the prearm checks pass
    run(sim, gcs, 0.1)
    assert gcs.acks(mavlink.MAV_CMD_COMPONENT_ARM_DISARM) == [mavlink.MAV_RESULT_ACCEPTED]
    gcs.disarm()
    run(sim, gcs, 3.0)
    flags = gcs.last["EKF_STATUS_REPORT"].flags
    assert flags & mavlink.EKF_POS_HORIZ_ABS and not flags & mavlink.EKF_CONST_POS_MODE
    assert "HOME_POSITION" in gcs.last
    gcs.set_mode(GUIDED)
    run(sim, gcs, 0.1)
    assert gcs.acks(mavlink.MAV_CMD_DO_SET_MODE)[-1] == mavlink.MAV_RESULT_ACCEPTED


def test_px4_does_not_send_ardupilot_messages():
    sim, gcs = connect(autopilot="px4")
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT, 2)
    gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_EKF_STATUS_REPORT)
    run(sim, gcs, 2.0)
    assert "EKF_STATUS_REPORT" not in gcs.last
    # PX4 fails an interval and denies a single message it has no stream for.
    assert gcs.acks(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL) == [mavlink.MAV_RESULT_FAILED]
    assert gcs.acks(mavlink.MAV_CMD_REQUEST_MESSAGE) == [mavlink.MAV_RESULT_DENIED]
