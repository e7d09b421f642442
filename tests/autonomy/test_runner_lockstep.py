"""Lockstep runner: failures and limits end the flight with the vehicle brought down."""

from __future__ import annotations

from pathlib import Path

from autonomy.config import apply_overrides, load_mission
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
