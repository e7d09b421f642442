"""Properties of the SITL that must hold whatever a client sends."""

from __future__ import annotations

import math

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl
from sitl.copter.gcs import MiniGcs

DT = 0.05
coordinate = st.floats(-150.0, 150.0, allow_nan=False)


def _flying() -> tuple[Sitl, MiniGcs]:
    sim = Sitl()
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)
    gcs.keep = False
    gcs.heartbeat()
    for _ in range(int(sim.settings.arming_settle_time / DT) + 2):
        sim.step(DT)
    gcs.set_mode(4)
    gcs.arm()
    gcs.takeoff(10.0)
    for _ in range(int(8.0 / DT)):
        sim.step(DT)
    return sim, gcs


@settings(max_examples=15, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(north=coordinate, east=coordinate, up=st.floats(2.0, 60.0))
def test_speeds_stay_within_the_airframe_limits(north, east, up):
    sim, gcs = _flying()
    s = sim.settings
    gcs.goto_ned(north, east, -up)
    for _ in range(int(20.0 / DT)):
        sim.step(DT)
        gcs.poll()
        vx, vy, vz = sim.truth.velocity
        assert math.hypot(vx, vy) <= s.max_horizontal_speed + 1e-6
        assert -s.max_descent_speed - 1e-6 <= vz <= s.max_climb_speed + 1e-6
    assert not sim.truth.crashed


@settings(max_examples=25, deadline=None, derandomize=True)
@given(garbage=st.lists(st.binary(min_size=0, max_size=64), min_size=1, max_size=6))
def test_garbage_between_packets_never_stops_valid_commands(garbage):
    sim = Sitl()
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)
    for chunk in garbage:
        link.gcs.write(chunk)
        gcs.heartbeat()
        sim.step(DT)
    # A stray start byte makes pymavlink's parser take up to a full-length packet (280
    # bytes) before the CRC fails; it then drops those bytes, valid packets among them, and
    # may land mid-packet again. A real client re-sends until it gets its ACK: so here.
    for _ in range(60):
        gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        sim.step(DT)
        gcs.poll()
        if gcs.acks(mavlink.MAV_CMD_REQUEST_MESSAGE):
            break
    assert gcs.acks(mavlink.MAV_CMD_REQUEST_MESSAGE)[-1] == mavlink.MAV_RESULT_ACCEPTED
    assert "HEARTBEAT" in gcs.counts
