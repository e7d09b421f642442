"""End to end (issue 18, seed 004): lockstep flights whose descent to the verification
altitude is watched by the optical flow of the textured camera.

The world is an elevation model with one 12 m tower; the thresholds come from
``calibrate_descent`` over an open column of the same world, as docs/obstacle-avoidance.md
says. A site 3.5 m beside the tower: the watch flags it during the descent and the vehicle
steps away from it (west) before going on down; a site on open ground: it descends straight.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from autonomy.config import Mission
from autonomy.perception.descent_flow import calibrate_descent
from autonomy.perception.descent_flow_settings import DescentFlowSettings
from autonomy.runner import fly
from autonomy.runner.world import build_terrain

CELL = 0.25
MAX_OFFSET = 6.0  # m from the site column
SIDE = 80.0  # m; home at the model's centre
TOWER = (18.5, 22.5, -2.0, 2.0, 12.0)  # ENU x0, x1, y0, y1 (m about home), height (m)
CAMERA = {"width": 160, "height": 120, "focal_px": 80.0, "rate": 5.0, "max_corners": 500,
          "min_distance": 5}


@functools.lru_cache(maxsize=1)
def _elevation(directory: str) -> str:
    n = int(SIDE / CELL) + 1
    enu = np.arange(n) * CELL - SIDE / 2
    x0, x1, y0, y1, height = TOWER
    grid = np.zeros((n, n), np.float32)  # row i along +y (north), as .npy models are read
    grid[np.ix_((enu >= y0) & (enu <= y1), (enu >= x0) & (enu <= x1))] = height
    path = f"{directory}/tower.npy"
    np.save(path, grid)
    return path


def _mission(path: str, site: tuple[float, float], flow: dict) -> Mission:
    return Mission.model_validate({
        "name": "descent watch",
        "cruise_altitude": 20.0,
        "waypoints": [[site[0] - 6.0, site[1], 20.0]],
        "landing": {
            "verify": False,
            "clear_altitude_buffer": 10.0,
            "search_rectangle": [10.0, 10.0],
            "pattern_center_radius": 5.0,
            "descent_watch": {"enabled": True, "step": 2.0, "max_offset": MAX_OFFSET},
        },
        "world": {"kind": "file", "path": path, "source_cell_size": CELL, "cell_size": CELL},
        "sitl": {"wind": {"speed": 0.0}},
        "perception": {"detector": "scripted", "rate": 2.0, "scripted": {"fov": 90.0},
                       "descent_flow": flow},
        "sites": [{"x": site[0], "y": site[1], "size": 4.0}],
        "seed": 3,
        "time_limit": 150.0,
    })


@pytest.fixture(scope="module")
def flow_settings(tmp_path_factory):
    path = _elevation(str(tmp_path_factory.mktemp("world")))
    terrain = build_terrain(_mission(path, (0.0, 0.0), CAMERA), seed=0)
    o_t, v_t, pairs = calibrate_descent(terrain, -20.0, 20.0,
                                        settings=DescentFlowSettings(**CAMERA), top=22.0)
    assert pairs > 30
    return path, {**CAMERA, "obstacle_threshold": o_t, "variance_threshold": v_t}


def _descent(result):
    """(positions during the descent phase, the watch's obstacle events)."""
    t, xyz, _ = result.data.trace.arrays()
    phases = result.data.trace.phases
    start = next(when for when, phase in phases if phase == "descend")
    end = next((when for when, phase in phases if when > start and phase != "descend"), t[-1])
    obstacles = [e for e in result.events if e.get("event") == "descent_obstacle"]
    return xyz[(t >= start) & (t <= end)], obstacles


def test_a_tower_beside_the_descent_is_flagged_and_stepped_away_from(flow_settings):
    path, flow = flow_settings
    site = (15.0, 0.0)  # the tower's west face is 3.5 m east of the column
    result = fly(_mission(path, site, flow))
    assert result.outcome == "landed"
    track, obstacles = _descent(result)
    assert obstacles, "the tower was never flagged"
    first = obstacles[0]
    assert first["position"][2] > TOWER[4]  # seen from above its top, before passing it
    # Stepped west, away from the tower, by at most the offset bound.
    west = site[0] - track[:, 0]
    offset = np.hypot(track[:, 0] - site[0], track[:, 1] - site[1])
    assert west.max() >= 1.9 and offset.max() <= MAX_OFFSET + 0.3
    assert track[-1, 2] < 4.0  # and went on down to the verification altitude
    assert result.summary["touchdown"]["x"] < site[0] - 1.0


def test_over_open_ground_the_descent_goes_straight_down(flow_settings):
    path, flow = flow_settings
    site = (-15.0, -12.0)
    result = fly(_mission(path, site, flow))
    assert result.outcome == "landed"
    track, obstacles = _descent(result)
    assert obstacles == []
    assert np.hypot(track[:, 0] - site[0], track[:, 1] - site[1]).max() < 0.5
    assert track[0, 2] - track[-1, 2] > 12.0  # a real descent was watched
