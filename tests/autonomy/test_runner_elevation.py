"""The runner with the elevation-map detector: sites come from the simulated depth camera."""

from __future__ import annotations

from autonomy.config import parse_mission
from autonomy.runner import fly

# A small, quick mission: flat world, a low survey and a coarse camera and map.
MISSION = """\
name: elevation-small
cruise_altitude: 15.0
waypoints:
  - [25.0, 0.0, 15.0]
landing: {verification_duration: 6.0}
world: {kind: flat, size: [120.0, 120.0], cell_size: 0.5}
lsm: {match_radius: 3.0}
sitl: {arming_settle_time: 2.0}
perception:
  detector: elevation_map
  rate: 1.0
  camera: {width: 64, height: 64, focal_px: 32.0}
  elevation_map: {size: 30.0, resolution: 0.5, fine_below: 0.0}  # coarse map only: quick
seed: 3
"""


def test_elevation_map_sites_are_verified_and_landed_on():
    mission = parse_mission(MISSION, "small.yaml")
    result = fly(mission)
    summary = result.summary
    assert summary["detector"] == "elevation_map"
    assert summary["outcome"] == "landed" and summary["touchdown_safe"] is True
    assert summary["sites_verified"] >= 1 and summary["verification_attempts"] >= 1
    assert summary["touchdown_error"] <= mission.lsm.match_radius
    assert summary["perception"]["observations"] > 0
    # The camera switched between structure from motion and stereo on the way.
    switches = [e["source"] for e in result.events
                if e["kind"] == "perception" and e.get("event") == "depth_source"]
    assert "sfm" in switches and "stereo" in switches


def test_perception_runs_faster_below_the_low_altitude():
    # Same mission, 1 Hz everywhere vs 5 Hz below 10 m AGL (the descent and the hover).
    base = parse_mission(MISSION, "small.yaml")
    fast = parse_mission(
        MISSION.replace("  rate: 1.0\n", "  rate: 1.0\n  low_altitude_rate: 5.0\n"
                        "  low_altitude: 10.0\n"), "small.yaml")
    base_summary, fast_summary = fly(base).summary, fly(fast).summary
    assert fast_summary["outcome"] == "landed" and fast_summary["touchdown_safe"] is True
    base_rate = base_summary["perception"]["updates"] / base_summary["mission_time"]
    fast_rate = fast_summary["perception"]["updates"] / fast_summary["mission_time"]
    assert fast_rate > 1.5 * base_rate
    assert base_rate <= 1.05  # 1 Hz when nothing says otherwise
