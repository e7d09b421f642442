"""A flight through the driver against PX4's SITL with the SIH quadrotor (real time, UDP).

Skipped unless PX4_SITL names a PX4 SITL ``px4`` binary (in a PX4-Autopilot checkout:
``make px4_sitl_default`` -> build/px4_sitl_default/bin/px4). The test runs it with
PX4_SYS_AUTOSTART=10040 (SIH quadrotor), PX4_SIMULATOR=sihsim, PX4_SIM_MODEL=sihsim_quadx and
``-d`` in a temporary working directory; PX4 sends its ground-station link to
udp 127.0.0.1:14550, where the driver listens.
Optional: PX4_SPEEDUP = PX4_SIM_SPEED_FACTOR (default 1).
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from behaviors.ports import CommandStatus

BINARY = os.environ.get("PX4_SITL", "")
pytestmark = [
    pytest.mark.skipif(not BINARY, reason="set PX4_SITL to a PX4 SITL px4 binary"),
    pytest.mark.timeout(900),
]


def test_offboard_flight_on_px4(start_sitl, live_flight, tmp_path):
    flight = live_flight("udpin:127.0.0.1:14550")  # listen before PX4 starts sending
    v = flight.vehicle
    binary = Path(BINARY).expanduser().resolve()
    env = {
        "PX4_SYS_AUTOSTART": "10040",
        "PX4_SIMULATOR": "sihsim",
        "PX4_SIM_MODEL": "sihsim_quadx",
        "PX4_SIM_SPEED_FACTOR": os.environ.get("PX4_SPEEDUP", "1"),
        "HEADLESS": "1",
    }
    rootfs = tmp_path / "rootfs"
    rootfs.mkdir()
    # px4 [-d] [-w working_directory] [data_path]: data_path is the build's etc/ folder.
    start_sitl([str(binary), "-d", "-w", str(rootfs), str(binary.parent.parent / "etc")], env)

    s = flight.until(lambda s: not s.link_lost, 60, "heartbeat")
    assert s.autopilot == "px4"
    flight.until(lambda s: s.prearm_ok and s.home is not None, 240, "prearm checks and home")

    takeoff = flight.done(v.takeoff(10.0), timeout=30)
    assert takeoff.status is CommandStatus.ACCEPTED, takeoff.reason
    flight.until(lambda s: s.position[2] > 9.0, 120, "climb to 10 m")

    goto = flight.done(v.goto(20.0, 0.0, 10.0))
    assert goto.status is CommandStatus.ACCEPTED, goto.reason
    assert v.state.mode == "OFFBOARD"
    flight.until(lambda s: math.hypot(s.position[0] - 20.0, s.position[1]) < 1.0, 120, "goto")

    land = flight.done(v.land())
    assert land.status is CommandStatus.ACCEPTED, land.reason
    assert v.state.mode == "AUTO.LAND"
    s = flight.until(lambda s: not s.armed, 240, "land and disarm")
    assert abs(s.position[2]) < 1.0
