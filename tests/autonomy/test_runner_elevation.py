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
