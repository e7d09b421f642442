"""End to end (issue 18 part 4): lockstep flights in a world where a person walks onto the
landing site after takeoff.

The small elevation-map mission of tests/autonomy/test_runner_elevation.py picks the site at
home it saw on takeoff. A person walks 15 m onto it and stays. With ``verify_fresh`` the
hover at 2.5 m must re-detect the site: the person stands in the way, the site is banned
and another one landed on, clear of the person. Without it the takeoff look verifies the
site at once, and the ground truth calls the touchdown beside the person unsafe and counts
the vehicle's contact with them as a collision.
"""

from __future__ import annotations

import math

from autonomy.config import parse_mission
from autonomy.runner import fly

PERSON = (-0.25, -0.25)  # where the person stops: the site seen on takeoff
MISSION = f"""\
name: person on the site
cruise_altitude: 15.0
waypoints:
  - [25.0, 0.0, 15.0]
landing: {{verification_duration: 6.0, verify_fresh: FRESH}}
world:
  kind: flat
  size: [120.0, 120.0]
  cell_size: 0.5
  moving_obstacles:
    paths: [{{kind: person, path: [[{PERSON[0]}, -15.0], [{PERSON[0]}, {PERSON[1]}]],
              speed: 1.0, once: true}}]
lsm: {{match_radius: 3.0}}
sitl: {{arming_settle_time: 2.0}}
perception:
  detector: elevation_map
  rate: 1.0
  camera: {{width: 64, height: 64, focal_px: 32.0}}
  elevation_map: {{size: 30.0, resolution: 0.5, fine_below: 0.0}}
seed: 3
"""


def _fly(fresh: bool):
    return fly(parse_mission(MISSION.replace("FRESH", str(fresh).lower()), "person.yaml"))


def _from_person(point) -> float:
    return math.hypot(point["x"] - PERSON[0], point["y"] - PERSON[1])


def test_a_person_on_the_site_fails_its_verification_and_another_site_is_landed_on():
    result = _fly(fresh=True)
    summary = result.summary
    bans = [e for e in result.events if e.get("decision") == "banned"]
    assert bans, "the site under the person was never banned"
    first_banned = next(s for s in result.data.ban_zones)
    assert math.hypot(first_banned[0] - PERSON[0], first_banned[1] - PERSON[1]) < 1.0
    assert summary["verification_attempts"] >= 2
    assert summary["outcome"] == "landed" and summary["touchdown_safe"] is True
    assert _from_person(summary["touchdown"]) > 1.5 + 0.3  # clearance + the person's radius
    assert summary["collisions"] == 0 and summary["first_collision"] is None


def test_a_touchdown_beside_a_person_is_unsafe_and_the_contact_a_collision():
    result = _fly(fresh=False)  # verified by the takeoff look: lands on the person
    summary = result.summary
    assert summary["sites_banned"] == 0
    assert _from_person(summary["touchdown"]) < 1.0
    # The rotors hit the person on the way down: a crash, whatever the ground was.
    assert summary["outcome"] == "crashed" and summary["exit_code"] == 1
    assert summary["crash_reason"].startswith("collision with the person at ")
    assert summary["touchdown_safe"] is False
    assert summary["collisions"] == 1
    assert summary["first_collision"]["obstacle"] == "person"
    assert summary["first_collision"]["t"] < summary["touchdown"]["t"]
    assert [e["obstacle"] for e in result.events if e.get("event") == "collision"] == ["person"]
