"""GPS loss and the laser light sensors in the embedded SITL, seen over MAVLink."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl, SitlSettings
from sitl.copter.gcs import MiniGcs
from sitl.sensors.laser import DOWN_BIT, MESSAGE_NAME, LaserSettings, LightSensorRing

GUIDED, LAND = 4, 9
DT = 0.1


def _flat(x, y):
    return np.zeros(np.broadcast(np.asarray(x), np.asarray(y)).shape)


class Ridge:
    """A 60 m high wall across x = 50 m."""

    def height(self, x, y):
        x, y = np.broadcast_arrays(np.asarray(x, float), np.asarray(y, float))
        return np.where(np.abs(x - 50.0) < 5.0, 60.0, 0.0)


def connect(settings: SitlSettings, autopilot="ardupilot", terrain=None, seed=0):
    sim = Sitl(settings, autopilot=autopilot, terrain=terrain, seed=seed)
    link = MemoryLink()
    sim.attach(link.vehicle)
    return sim, MiniGcs(link.gcs)


def run(sim, gcs, seconds, until=None) -> bool:
    end = sim.time + seconds
    while sim.time < end - 1e-9:
        sim.step(DT)
        gcs.poll()
        if until is not None and until():
            return True
    return until is None


def airborne(sim, gcs, altitude=20.0, px4=False):
    gcs.heartbeat()
    for name in ("GLOBAL_POSITION_INT", "LOCAL_POSITION_NED", "GPS_RAW_INT", "SYS_STATUS"):
        gcs.set_interval(getattr(mavlink, f"MAVLINK_MSG_ID_{name}"), 5)
    run(sim, gcs, sim.settings.arming_settle_time + 0.2)
    if px4:
        gcs.arm()
        gcs.command(mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan,
                    sim.settings.home.alt + altitude)
    else:
        gcs.set_mode(GUIDED)
        gcs.arm()
        gcs.takeoff(altitude)
    assert run(sim, gcs, 40, until=lambda: sim.truth.position[2] > altitude - 0.3)


# ----------------------------------------------------------------- light sensors
def _ring(**kwargs) -> LightSensorRing:
    settings = LaserSettings(**{"emitter": (100.0, 0.0), "reflection_rate": 0.0, **kwargs})
    return LightSensorRing(settings, _flat, np.random.default_rng(1))


def _lit(mask: int) -> list[int]:
    return [i for i in range(13) if mask >> i & 1]


def test_the_sensor_facing_the_laser_lights_and_turning_moves_it():
    ring = _ring(condition="night", emitter=(30.0, 0.0))
    # Emitter due east (heading 90 deg clockwise from north): nose north -> sensor 3.
    assert _lit(ring.read((0.0, 0.0, 10.0), 0.0)) == [3]
    assert _lit(ring.read((0.0, 0.0, 10.0), math.radians(90.0))) == [0]
    assert _lit(ring.read((0.0, 0.0, 10.0), math.radians(-60.0))) == [5]


def test_neighbours_light_at_range_and_the_downward_sensor_over_the_emitter():
    ring = _ring(condition="night", emitter=(0.0, 0.0))
    near = _lit(ring.read((0.0, -20.0, 5.0), 0.0))  # emitter due north, 20 m
    far = _lit(ring.read((0.0, -400.0, 5.0), 0.0))
    assert near == [0]
    assert len(far) >= 3 and 0 in far and {1, 11} <= set(far)
    assert _lit(ring.read((1.0, 1.0, 30.0), 0.0)) == [12]
    assert ring.read((1.0, 1.0, 30.0), 0.0) & DOWN_BIT


def test_ambient_light_by_condition_decides_the_range():
    # Table 2: a sunny sky drowns the laser far sooner than the night.
    sunny, night = _ring(condition="sunny"), _ring(condition="night")
    assert sunny.read((60.0, 0.0, 2.0), 0.0) != 0  # 40 m
    assert sunny.read((-200.0, 0.0, 2.0), 0.0) == 0  # 300 m
    assert night.read((-200.0, 0.0, 2.0), 0.0) != 0
    assert _ring(condition="sunny", power=30.0).read((-200.0, 0.0, 2.0), 0.0) != 0


def test_terrain_blocks_the_beam_and_reflections_light_random_sensors():
    settings = LaserSettings(emitter=(100.0, 0.0), condition="night", reflection_rate=0.0)
    ring = LightSensorRing(settings, Ridge().height, np.random.default_rng(2))
    assert not ring.line_of_sight((0.0, 0.0, 10.0))
    assert ring.read((0.0, 0.0, 10.0), 0.0) == 0
    assert ring.line_of_sight((0.0, 0.0, 200.0))
    noisy = LightSensorRing(
        settings.model_copy(update={"emitter": None, "reflection_rate": 0.5}).model_copy(
            update={"emitter": (5000.0, 0.0)}
        ),
        Ridge().height,
        np.random.default_rng(3),
    )
    masks = [noisy.read((0.0, 0.0, 10.0), 0.0) for _ in range(400)]
    # Behind the ridge: only reflections, one sensor at a time, about half the readings.
    assert all(bin(m).count("1") <= 1 for m in masks)
    assert 150 < sum(m != 0 for m in masks) < 250
    assert len({m for m in masks if m}) >= 10


def test_light_sensors_are_published_as_named_value_int_only_when_fitted():
    plain, gcs = connect(SitlSettings())
    gcs.heartbeat()
    run(plain, gcs, 3.0)
    assert not gcs.of_type("NAMED_VALUE_INT")
    laser = LaserSettings(emitter=(0.0, 60.0), condition="night", reflection_rate=0.0)
    sim, gcs = connect(SitlSettings(laser=laser))
    airborne(sim, gcs, altitude=10.0)
    run(sim, gcs, 2.0)
    values = [m for m in gcs.of_type("NAMED_VALUE_INT") if m.name == MESSAGE_NAME]
    assert len(values) >= 15  # 10 Hz
    assert values[-1].value == 1  # sensor 0, the nose points north at the emitter
    assert values[-1].time_boot_ms == pytest.approx(sim.time * 1000, abs=150)
    # Fitted but no laser: ambient light lights nothing (reflections aside).
    dark, gcs = connect(SitlSettings(laser=LaserSettings(condition="sunny", reflection_rate=0)))
    gcs.heartbeat()
    run(dark, gcs, 3.0)
    values = [m.value for m in gcs.of_type("NAMED_VALUE_INT") if m.name == MESSAGE_NAME]
    assert len(values) >= 25 and set(values) == {0}


# ----------------------------------------------------------------- GPS loss
def test_gps_loss_drops_the_fix_and_the_estimate_drifts_while_velocity_still_steers():
    loss = {"at": 15.0, "drift_bias": 0.3}
    sim, gcs = connect(SitlSettings.model_validate({"gps_loss": loss}), seed=4)
    airborne(sim, gcs)
    assert gcs.last["GPS_RAW_INT"].fix_type == 3
    run(sim, gcs, 15.0 - sim.time + 0.5)
    texts = gcs.texts()
    assert "EKF3 IMU0 is using optical flow" in texts
    run(sim, gcs, 1.0)
    gps = gcs.last["GPS_RAW_INT"]
    assert gps.fix_type == mavlink.GPS_FIX_TYPE_NO_FIX and gps.satellites_visible == 0
    assert not gcs.last["SYS_STATUS"].onboard_control_sensors_health & (
        mavlink.MAV_SYS_STATUS_SENSOR_GPS
    )
    start = sim.truth.position
    for _ in range(100):  # 10 s east at 2 m/s, refreshed like a companion does
        gcs.velocity_ned(0.0, 2.0, 0.0)
        run(sim, gcs, DT)
    moved = np.subtract(sim.truth.position, start)
    assert moved[0] == pytest.approx(20.0, abs=3.0) and abs(moved[1]) < 1.0
    lpn = gcs.last["LOCAL_POSITION_NED"]
    error = math.hypot(lpn.y - sim.truth.position[0], lpn.x - sim.truth.position[1])
    assert error > 0.5  # the reported position is off the truth, and grows
    run(sim, gcs, 20.0)
    lpn = gcs.last["LOCAL_POSITION_NED"]
    assert math.hypot(lpn.y - sim.truth.position[0], lpn.x - sim.truth.position[1]) > error
    assert sim.truth.mode == "GUIDED"  # optical flow keeps GUIDED flying


def test_position_targets_are_flown_in_the_drifting_frame():
    loss = {"at": 12.0, "drift_bias": 0.5}
    sim, gcs = connect(SitlSettings.model_validate({"gps_loss": loss}), seed=5)
    airborne(sim, gcs)
    run(sim, gcs, 30.0)
    for _ in range(60):  # "home, 20 m up" in the EKF's frame, streamed like a companion does
        gcs.goto_ned(0.0, 0.0, -20.0)
        run(sim, gcs, 0.5)
    truth = sim.truth.position
    lpn = gcs.last["LOCAL_POSITION_NED"]
    assert math.hypot(lpn.x, lpn.y) < 2.0  # the estimate says it is there ...
    assert math.hypot(truth[0], truth[1]) > 5.0  # ... it is not


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_without_velocity_aiding_the_position_failsafe_lands(autopilot):
    loss = {"at": 25.0, "velocity_aiding": False}
    sim, gcs = connect(SitlSettings.model_validate({"gps_loss": loss}), autopilot=autopilot)
    px4 = autopilot == "px4"
    airborne(sim, gcs, px4=px4)

    def hover(seconds):  # a companion streaming "stay here" by velocity
        for _ in range(round(seconds / DT)):
            gcs.velocity_ned(0.0, 0.0, 0.0)
            run(sim, gcs, DT)

    if px4:
        hover(1.0)
        gcs.set_mode(sim.autopilot.modes["OFFBOARD"], px4=True)
    hover(2.0)
    assert sim.truth.mode == ("OFFBOARD" if px4 else "GUIDED")
    hover(25.0 - sim.time + 1.5)
    expected = "AUTO.LAND" if px4 else "LAND"
    assert sim.truth.mode == expected
    texts = " | ".join(gcs.texts())
    assert ("no local position" in texts) if px4 else ("EKF Failsafe: changed to LAND" in texts)
    gcs.set_mode(sim.autopilot.modes["OFFBOARD" if px4 else "GUIDED"], px4=px4)
    run(sim, gcs, 1.0)
    assert sim.truth.mode == expected  # no position: the position modes stay refused
    assert run(sim, gcs, 120.0, until=lambda: not sim.truth.armed)


def test_gps_comes_back_after_its_duration():
    loss = {"at": 12.0, "duration": 5.0}
    sim, gcs = connect(SitlSettings.model_validate({"gps_loss": loss}))
    airborne(sim, gcs)
    run(sim, gcs, 14.0 - sim.time)
    assert gcs.last["GPS_RAW_INT"].fix_type == mavlink.GPS_FIX_TYPE_NO_FIX
    run(sim, gcs, 5.0)
    assert gcs.last["GPS_RAW_INT"].fix_type == 3
    assert "GPS 1: fix regained" in gcs.texts()
    lpn = gcs.last["LOCAL_POSITION_NED"]
    assert (lpn.y, lpn.x) == pytest.approx(sim.truth.position[:2], abs=0.2)
