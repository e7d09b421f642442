"""End to end: GPS lost mid-mission in lockstep on the embedded SITL. With a ground laser at
a safe point the tree follows it and lands there; without one it lands in place."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml

from autonomy.cli import main
from autonomy.config import Mission
from autonomy.runner import fly

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"
EMITTER = (70.0, 70.0)  # flat ground, 40-70 m from where GPS is lost
LANDING_TOLERANCE = 2.0  # m from the emitter


def gps_denied_demo(laser: dict | None, autopilot: str = "ardupilot") -> dict:
    """The demo mission, GPS lost 25 s after boot (on the way to the second waypoint)."""
    data = yaml.safe_load(DEMO.read_text())
    data["vehicle"]["autopilot"] = autopilot
    data["sitl"]["gps_loss"] = {"at": 25.0}
    if laser is not None:
        data["sitl"]["laser"] = laser
    data["landing"]["gps_loss_timeout"] = 3.0
    data["landing"]["laser_guidance"] = {"wait_timeout": 10.0}
    return data


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_laser_guides_the_vehicle_to_land_beside_it(autopilot):
    laser = {"emitter": list(EMITTER), "condition": "night"}
    result = fly(Mission.model_validate(gps_denied_demo(laser, autopilot)))
    summary = result.summary
    assert summary["outcome"] == "landed", summary.get("failure_reason")
    assert summary["outcome_hint"] == "laser_guidance"
    assert summary["touchdown_safe"] is True
    touchdown = summary["touchdown"]
    assert math.hypot(touchdown["x"] - EMITTER[0], touchdown["y"] - EMITTER[1]) <= (
        LANDING_TOLERANCE
    )


def test_without_a_laser_the_vehicle_lands_in_place_after_its_wait():
    # The light sensors are on board, but nobody aims a laser at them.
    result = fly(Mission.model_validate(gps_denied_demo({"condition": "night"})))
    summary = result.summary
    assert summary["outcome"] == "failsafe"
    assert summary["outcome_hint"] == "gps_lost"
    touchdown = summary["touchdown"]
    # Landed near where GPS was lost (between the first two waypoints), not at the emitter.
    assert 35.0 <= touchdown["x"] <= 45.0 and touchdown["y"] <= 40.0
    # The reason the guidance gave up is in the flight's log.
    reasons = [e["feedback"] for e in result.events if e.get("behaviour") == "Follow the laser"
               and e.get("new") == "FAILURE"]
    assert reasons == ["no laser within 10 s"]


def test_validate_names_a_bad_emitter_in_one_line(tmp_path, capsys):
    data = gps_denied_demo({"emitter": [70.0, 1e9], "condition": "dusk"})
    path = tmp_path / "gps.yaml"
    path.write_text(yaml.safe_dump(data))
    assert main(["validate", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and "Traceback" not in "".join(err)
    assert "sitl.laser.condition: must be 'sunny', 'cloudy', 'night' or 'indoor'" in err[0]
    assert "sitl.laser.emitter.1: must be <= 50000.0" in err[1]
