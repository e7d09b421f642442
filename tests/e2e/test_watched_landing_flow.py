"""End to end (issue 18): the optical flow's part in watching the landing.

A car drives a long lane whose west side passes 0.6 m from the landing column of a flat
world, timed to come by while the vehicle lands on the first site (below the verification
altitude, where the descent's own watch has ended). Without the watch the car runs into the
landing vehicle: a collision. With it, the flow sees the car come into the frame beside the
landing before the rangefinder could read it under the vehicle: the landing is aborted (a
climb out of LAND), the site banned, and the next try lands on the second site, 14 m north.
The flow thresholds come from ``calibrate_descent`` over an open column of the same world,
as docs/obstacle-avoidance.md says.
"""

from __future__ import annotations

import numpy as np
import pytest

from autonomy.config import Mission
from autonomy.perception.descent_flow import calibrate_descent
from autonomy.perception.descent_flow_settings import DescentFlowSettings
from autonomy.runner import fly
from autonomy.runner.world import build_terrain

SITE, SECOND = (15.0, 0.0), (15.0, 14.0)
LANE_X, LANE_Y, SPEED = 16.6, 60.0, 4.0  # the car: centre line, half the lane, m/s
CAMERA = {"width": 160, "height": 120, "focal_px": 80.0, "rate": 5.0, "max_corners": 500}


def _mission(flow: dict, *, watch: bool, car_start: float | None) -> Mission:
    moving = None if car_start is None else {"paths": [{
        "kind": "vehicle", "path": [[LANE_X, -LANE_Y], [LANE_X, LANE_Y]], "speed": SPEED,
        "start": car_start}]}
    return Mission.model_validate({
        "name": "car passing the landing",
        "cruise_altitude": 20.0,
        "waypoints": [[SITE[0] - 6.0, SITE[1], 20.0]],
        "landing": {"verify": False, "clear_altitude_buffer": 10.0,
                    "descent_watch": {"enabled": watch, "step": 2.0, "max_offset": 6.0}},
        "world": {"kind": "flat", "size": [140.0, 140.0], "cell_size": 0.25,
                  "moving_obstacles": moving},
        "sitl": {"wind": {"speed": 0.0}},
        "perception": {"detector": "scripted", "rate": 2.0, "scripted": {"fov": 90.0},
                       "descent_flow": flow},
        "sites": [{"x": SITE[0], "y": SITE[1], "size": 4.0},
                  {"x": SECOND[0], "y": SECOND[1], "size": 3.0}],
        "seed": 3,
        "time_limit": 150.0,
    })


@pytest.fixture(scope="module")
def flow():
    terrain = build_terrain(_mission(CAMERA, watch=True, car_start=None), seed=0)
    o_t, v_t, pairs = calibrate_descent(terrain, -20.0, 20.0,
                                        settings=DescentFlowSettings(**CAMERA), top=22.0)
    assert pairs > 30
    return {**CAMERA, "obstacle_threshold": o_t, "variance_threshold": v_t}


@pytest.fixture(scope="module")
def car_start(flow):
    """Metres along the car's round at t = 0 that bring it abreast of the site 2.7 s after
    the landing begins (the car drives south first, turns at the lane's end, comes north),
    read off the same flight without the car: out of the frame during the descent."""
    alone = fly(_mission(flow, watch=True, car_start=None))
    assert alone.outcome == "landed" and alone.summary["touchdown_safe"] is True
    touchdown = alone.summary["touchdown"]
    assert np.hypot(touchdown["x"] - SITE[0], touchdown["y"] - SITE[1]) < 0.5
    assert [e for e in alone.events if e.get("event") == "descent_obstacle"] == []
    landing = next(when for when, phase in alone.data.trace.phases if phase == "land")
    round_trip = 4.0 * LANE_Y
    return (round_trip + LANE_Y - SPEED * (landing + 2.7)) % round_trip


def test_the_blind_landing_is_run_into_by_the_passing_car(flow, car_start):
    result = fly(_mission(flow, watch=False, car_start=car_start))
    assert result.summary["collisions"] >= 1
    assert result.outcome == "crashed"
    touchdown = result.summary["touchdown"]
    assert np.hypot(touchdown["x"] - SITE[0], touchdown["y"] - SITE[1]) < 0.5


def test_the_flow_aborts_the_landing_beside_the_car_and_the_next_site_is_landed_on(
        flow, car_start):
    result = fly(_mission(flow, watch=True, car_start=car_start))
    assert result.outcome == "landed"
    assert result.summary["collisions"] == 0
    assert result.summary["touchdown_safe"] is True
    touchdown = result.summary["touchdown"]
    assert np.hypot(touchdown["x"] - SECOND[0], touchdown["y"] - SECOND[1]) < 3.0
    aborted = [e for e in result.events if e.get("behaviour") == "Land (watched)"
               and e.get("new") == "FAILURE"]
    assert len(aborted) == 1
    # The flow's sighting ("beside the landing"), not the rangefinder's column reading.
    assert "beside the landing" in aborted[0]["feedback"]
    assert "entered the column" not in aborted[0]["feedback"]
    assert "banned" in aborted[0]["feedback"]
    assert result.summary["sites_banned"] == 1
