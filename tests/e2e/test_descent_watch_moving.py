"""End to end (issue 18 part 4 with part 3's descent watch): a car drives up and down a lane
beside the descent column of a flat world. The watch's optical flow sees it (its own texture
moves with it in the greyscale frames) and the vehicle steps away from it, west, before going
on down; the thresholds come from ``calibrate_descent`` over an open column of the same world,
as docs/obstacle-avoidance.md says. Without the car the same descent is not flagged."""

from __future__ import annotations

import numpy as np
import pytest

from autonomy.config import Mission
from autonomy.perception.descent_flow import calibrate_descent
from autonomy.perception.descent_flow_settings import DescentFlowSettings
from autonomy.runner import fly
from autonomy.runner.world import build_terrain

SITE = (15.0, 0.0)
LANE_X = 18.5  # the car's centre line: its west side 2.5 m east of the column
CAMERA = {"width": 160, "height": 120, "focal_px": 80.0, "rate": 5.0, "max_corners": 500}
MAX_OFFSET = 6.0


def _mission(flow: dict, car: bool = True) -> Mission:
    moving = {"paths": [{"kind": "vehicle", "path": [[LANE_X, -15.0], [LANE_X, 15.0]],
                         "speed": 4.0}]} if car else None
    return Mission.model_validate({
        "name": "car beside the descent",
        "cruise_altitude": 20.0,
        "waypoints": [[SITE[0] - 6.0, SITE[1], 20.0]],
        "landing": {
            "verify": False,
            "clear_altitude_buffer": 10.0,
            "search_rectangle": [10.0, 10.0],
            "pattern_center_radius": 5.0,
            "descent_watch": {"enabled": True, "step": 2.0, "max_offset": MAX_OFFSET},
        },
        "world": {"kind": "flat", "size": [80.0, 80.0], "cell_size": 0.25,
                  "moving_obstacles": moving},
        "sitl": {"wind": {"speed": 0.0}},
        "perception": {"detector": "scripted", "rate": 2.0, "scripted": {"fov": 90.0},
                       "descent_flow": flow},
        "sites": [{"x": SITE[0], "y": SITE[1], "size": 4.0}],
        "seed": 3,
        "time_limit": 150.0,
    })


@pytest.fixture(scope="module")
def flow():
    terrain = build_terrain(_mission(CAMERA), seed=0)
    o_t, v_t, pairs = calibrate_descent(terrain, -20.0, 20.0,
                                        settings=DescentFlowSettings(**CAMERA), top=22.0)
    assert pairs > 30
    return {**CAMERA, "obstacle_threshold": o_t, "variance_threshold": v_t}


def test_a_car_driving_beside_the_descent_is_flagged_and_stepped_away_from(flow):
    result = fly(_mission(flow))
    assert result.outcome == "landed"
    t, xyz, _ = result.data.trace.arrays()
    start = next(when for when, phase in result.data.trace.phases if phase == "descend")
    track = xyz[t >= start]
    obstacles = [e for e in result.events if e.get("event") == "descent_obstacle"]
    assert obstacles, "the car was never flagged"
    assert track[:, 0].min() <= SITE[0] - 1.9  # stepped west, away from the lane
    assert np.hypot(track[:, 0] - SITE[0], track[:, 1] - SITE[1]).max() <= MAX_OFFSET + 0.3
    assert result.summary["collisions"] == 0


def test_without_the_car_the_same_descent_goes_straight_down(flow):
    result = fly(_mission(flow, car=False))
    assert result.outcome == "landed"
    assert [e for e in result.events if e.get("event") == "descent_obstacle"] == []
    touchdown = result.summary["touchdown"]
    assert np.hypot(touchdown["x"] - SITE[0], touchdown["y"] - SITE[1]) < 0.5
