"""Lockstep runner: failures and limits end the flight with the vehicle brought down."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
import yaml
from pymavlink import mavutil

from autonomy.cli import main
from autonomy.config import apply_overrides, geodetic_to_enu, load_mission
from autonomy.runner import fly

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"


def test_a_failed_mission_is_aborted_and_the_vehicle_landed():
    # Takeoff cannot reach 30 m within 2 s: the tree fails while the vehicle climbs.
    mission = apply_overrides(load_mission(DEMO), {"landing.navigation_timeout": 2.0})
    result = fly(mission)
    summary = result.summary
    assert summary["outcome"] == "aborted"
    assert summary["tree_status"] == "FAILURE"
    assert summary["failure_reason"]
    assert summary["stop_reason"].startswith("mission failed (land")
    assert summary["touchdown"] is not None and summary["touchdown"]["z"] < 0.5
    assert any(e["kind"] == "flight" and e.get("event") == "land" for e in result.events)


def test_the_time_limit_aborts_the_flight():
    mission = apply_overrides(load_mission(DEMO), {"time_limit": 20.0})
    summary = fly(mission).summary
    assert summary["outcome"] == "aborted"
    assert summary["stop_reason"].startswith("time limit")
    assert summary["tree_status"] == "RUNNING"


def test_no_sites_lands_in_place_with_no_site_outcome():
    mission = apply_overrides(load_mission(DEMO), {
        "sites": [], "landing.pattern_retries": 1, "landing.landing_retries": 1,
        "landing.search_rectangle": [20.0, 10.0],
    })
    summary = fly(mission).summary
    assert summary["outcome"] == "no_site"
    assert summary["search_patterns"] >= 1
    assert summary["touchdown"] is not None and summary["chosen_site"] is None


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_lat_lon_waypoint_is_reached_where_the_simulated_gps_reads_it(tmp_path, autopilot):
    """Lockstep converts lat/lon (waypoints, geofence vertices) as the embedded SITL's
    autopilot projects them, as a live flight does: the vehicle's own GPS (the tlog's
    GLOBAL_POSITION_INT) passes within the acceptance radius of a waypoint 1.8 km away,
    where the tangent plane missed it by metres (0.1-0.2 % of the distance)."""
    target = (47.397742 + 0.012, 8.545594 + 0.016)  # 1.33 km north, 1.21 km east of home
    data = yaml.safe_load(DEMO.read_text())
    data["vehicle"]["autopilot"] = autopilot
    data["waypoints"] = [{"lat": target[0], "lon": target[1], "alt": 35.0}, [0.0, 40.0, 35.0]]
    data["landing"]["acceptance_radius"] = 0.5
    data["time_limit"] = 900
    path = tmp_path / "far.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "out"
    assert main(["fly", str(path), "--quiet", "--out", str(out)]) == 0
    tlog = mavutil.mavlink_connection(str(out / "flight.tlog"))
    nearest = math.inf
    while (msg := tlog.recv_match(type="GLOBAL_POSITION_INT")) is not None:
        east, north = geodetic_to_enu(msg.lat * 1e-7, msg.lon * 1e-7, *target)
        nearest = min(nearest, math.hypot(east, north))
    assert nearest < 0.6, nearest
