"""End to end (issue 18): the landing from the verification altitude under the descent watch.

A car is parked on the best site's column of a flat world; a second site lies 12 m away.
Without the watch the blind descent stops 0.9 m above the roof and the landing sets the
vehicle down on it: a collision, an unsafe touchdown. With the watch, the rangefinder reads
the roof under the landing vehicle: the landing is aborted (a climb out of LAND back to the
verification altitude), the site is banned like one that fails verification, and the next
try lands on the other site. The flow thresholds are set out of reach so that this flight
shows the rangefinder's part alone (the flow's is tests/e2e/test_descent_watch_*.py's).
"""

from __future__ import annotations

import numpy as np

from autonomy.config import Mission
from autonomy.runner import fly

BLOCKED, FREE = (15.0, 0.0), (15.0, 12.0)


def _mission(watch: bool) -> Mission:
    return Mission.model_validate({
        "name": "car parked on the site",
        "cruise_altitude": 20.0,
        "waypoints": [[BLOCKED[0] - 6.0, BLOCKED[1], 20.0]],
        "landing": {"verify": False, "clear_altitude_buffer": 5.0,
                    "descent_watch": {"enabled": watch}},
        "world": {"kind": "flat", "size": [60.0, 60.0], "cell_size": 0.5,
                  "moving_obstacles": {"paths": [
                      {"kind": "vehicle", "path": [list(BLOCKED)], "speed": 0.0}]}},
        "sitl": {"wind": {"speed": 0.0}},
        "perception": {"detector": "scripted", "rate": 2.0, "scripted": {"fov": 90.0},
                       "descent_flow": {"width": 80, "height": 60, "focal_px": 40.0,
                                        "min_distance": 3, "obstacle_threshold": 1e6,
                                        "variance_threshold": 1e12}},
        "sites": [{"x": BLOCKED[0], "y": BLOCKED[1], "size": 6.0},
                  {"x": FREE[0], "y": FREE[1], "size": 3.0}],
        "seed": 1,
        "time_limit": 150.0,
    })


def test_the_blind_landing_comes_down_on_the_roof_of_a_parked_car():
    result = fly(_mission(watch=False))
    touchdown = result.summary["touchdown"]
    assert np.hypot(touchdown["x"] - BLOCKED[0], touchdown["y"] - BLOCKED[1]) < 1.0
    assert touchdown["z"] > 1.5  # on the roof, not through it
    assert result.summary["collisions"] >= 1
    assert result.summary["touchdown_safe"] is False


def test_the_watched_landing_climbs_off_the_car_bans_the_site_and_lands_on_the_next():
    result = fly(_mission(watch=True))
    assert result.outcome == "landed"
    assert result.summary["collisions"] == 0
    assert result.summary["touchdown_safe"] is True
    touchdown = result.summary["touchdown"]
    assert np.hypot(touchdown["x"] - FREE[0], touchdown["y"] - FREE[1]) < 1.0
    aborted = [e for e in result.events if e.get("behaviour") == "Land (watched)"
               and e.get("new") == "FAILURE"]
    assert len(aborted) == 1
    assert "entered the column" in aborted[0]["feedback"]
    assert "banned" in aborted[0]["feedback"]
    assert result.summary["sites_banned"] == 1
