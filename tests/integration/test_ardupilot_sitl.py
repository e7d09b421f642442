"""A flight through the driver against ArduPilot's own SITL (real time, TCP 5760).

Skipped unless ARDUPILOT_SITL names an ``arducopter`` SITL binary (in an ArduPilot checkout:
``./waf configure --board sitl && ./waf copter`` -> build/sitl/bin/arducopter). Optional:
ARDUPILOT_DEFAULTS = a parameter file (e.g. Tools/autotest/default_params/copter.parm),
ARDUPILOT_SPEEDUP = simulation speed-up (default 5).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from behaviors.ports import CommandStatus, LandedState

BINARY = os.environ.get("ARDUPILOT_SITL", "")
pytestmark = [
    pytest.mark.skipif(not BINARY, reason="set ARDUPILOT_SITL to an arducopter SITL binary"),
    pytest.mark.timeout(900),
]


def test_guided_flight_on_arducopter(start_sitl, live_flight):
    argv = [
        str(Path(BINARY).expanduser()),
        "--model",
        "quad",
        "--speedup",
        os.environ.get("ARDUPILOT_SPEEDUP", "5"),
        "-I0",
        "--home",
        "47.397742,8.545594,488,0",
        "--wipe",
    ]
    if os.environ.get("ARDUPILOT_DEFAULTS"):
        argv += ["--defaults", os.environ["ARDUPILOT_DEFAULTS"]]
    start_sitl(argv, tcp_port=5760)
    flight = live_flight("tcp:127.0.0.1:5760")
    v = flight.vehicle

    s = flight.until(lambda s: not s.link_lost, 30, "heartbeat")
    assert s.autopilot == "ardupilot"
    # ArduPilot judges its prearm bit for the current mode (STABILIZE); GUIDED also needs a
    # position estimate, or arming fails with "Arm: Need Position Estimate".
    flight.until(
        lambda s: s.prearm_ok and s.gps_fix >= 3 and s.position_estimate and s.home,
        240,
        "prearm checks, GPS fix, position estimate and home",
    )

    takeoff = flight.done(v.takeoff(10.0), timeout=30)
    assert takeoff.status is CommandStatus.ACCEPTED, takeoff.reason
    assert v.state.mode == "GUIDED" and v.state.armed
    flight.until(lambda s: s.position[2] > 9.0, 120, "climb to 10 m")

    goto = flight.done(v.goto(20.0, 0.0, 10.0))
    assert goto.status is CommandStatus.ACCEPTED, goto.reason
    s = flight.until(
        lambda s: math.hypot(s.position[0] - 20.0, s.position[1]) < 1.0, 120, "20 m east"
    )

    land = flight.done(v.land())
    assert land.status is CommandStatus.ACCEPTED, land.reason
    s = flight.until(lambda s: not s.armed, 240, "land and disarm")
    assert abs(s.position[2]) < 1.0
    assert math.hypot(s.position[0] - 20.0, s.position[1]) < 3.0
    assert s.landed_state in (LandedState.ON_GROUND, LandedState.UNDEFINED)
