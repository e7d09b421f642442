"""The mission's operating area (``geofence:``): validated through ``lander validate`` and
``lander fly``, respected by the Landing Site Manager, the search patterns, the pattern
centres and the approach, drawn and summarised in the report."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from matplotlib.path import Path as PolygonPath

from autonomy.cli import main
from autonomy.cli.demo import mission_path
from autonomy.config import load_mission
from autonomy.runner import fly

DEMO = mission_path("demo.yaml")
# Excludes the demo's second-best site (25, 55), where it lands without a geofence once
# the best (8, 46) fails verification; the third (55, 20) is inside.
DEMO_FENCE = {"polygon": [[-20, -20], [70, -20], [70, 50], [-20, 50]], "margin": 2,
              "max_altitude": 122}
# An L: the search rectangle around the last waypoint (0, 40) and most pattern centres
# drawn within 50 m of it would leave it.
L_FENCE = [[-30, -10], [60, -10], [60, 25], [20, 25], [20, 70], [-30, 70]]
SEARCH = {
    "name": "fenced search",
    "home": {"lat": 47.397742, "lon": 8.545594, "alt": 488.0},
    "cruise_altitude": 35.0,
    "waypoints": [[40.0, 0.0, 30.0], [40.0, 10.0, 35.0], [0.0, 10.0, 35.0], [0.0, 40.0, 35.0]],
    "landing": {"search_rectangle": [40.0, 30.0], "pattern_center_radius": 50.0,
                "pattern_retries": 2, "landing_retries": 2},
    "world": {"kind": "flat", "size": [200.0, 200.0], "cell_size": 0.5},
    "sitl": {"arming_settle_time": 3.0},
    "perception": {"detector": "scripted", "rate": 2.0},
    "geofence": {"polygon": L_FENCE, "margin": 3},
    "seed": 1,
    "time_limit": 1200.0,
}


def _demo_with(tmp_path, **changes) -> str:
    data = yaml.safe_load(DEMO.read_text())
    data.update(changes)
    path = tmp_path / "fenced.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return str(path)


def _error(capsys) -> str:
    (line,) = capsys.readouterr().err.strip().splitlines()
    return line


def test_a_demo_flight_lands_inside_the_area_not_on_the_best_site_outside(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["fly", _demo_with(tmp_path, geofence=DEMO_FENCE), "--quiet",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "landed"
    touchdown = summary["touchdown"]
    assert PolygonPath(DEMO_FENCE["polygon"]).contains_point((touchdown["x"], touchdown["y"]))
    assert abs(touchdown["x"] - 55.0) < 2 and abs(touchdown["y"] - 20.0) < 2
    assert summary["lsm_counters"]["rejected_outside_geofence"] > 0
    assert summary["geofence"] == DEMO_FENCE["polygon"]
    page = (out / "report.html").read_text()
    assert '"geofence":[[-20.0,-20.0],[70.0,-20.0]' in page.replace(" ", "")


def test_a_flight_without_a_geofence_reports_none():
    result = fly(load_mission(DEMO))
    assert "geofence" not in result.summary
    assert "rejected_outside_geofence" not in result.summary["lsm_counters"]
    touchdown = result.summary["touchdown"]
    assert abs(touchdown["x"] - 25.0) < 2 and abs(touchdown["y"] - 55.0) < 2


def test_search_patterns_and_pattern_centres_stay_inside_a_non_convex_area(tmp_path):
    path = tmp_path / "search.yaml"
    path.write_text(yaml.safe_dump(SEARCH))
    result = fly(load_mission(path))
    assert result.summary["search_patterns"] >= 3  # patterns around new centres were flown
    _, xyz, _ = result.data.trace.arrays()
    assert len(xyz) > 100
    inside = PolygonPath(L_FENCE).contains_points(xyz[:, :2])
    assert inside.all(), xyz[~inside][:3]
    # (without the area the same search leaves it: the rectangle around (0, 40) alone
    # reaches the edge at x = 20, and centres are drawn up to 50 m away)


@pytest.mark.parametrize(("fence", "field", "reason"), [
    ({"polygon": [[-20, -20], [70, 70], [70, -20], [-20, 70]]}, "geofence.polygon",
     "not a simple polygon"),
    ({"polygon": [[-20, -20], [70, -20]]}, "geofence.polygon", "at least 3 items"),
    ({"polygon": [[0, 0], [1, 1], [2, 2]]}, "geofence.polygon", "encloses no area"),
    ({"polygon": [[5, -20], [70, -20], [70, 50], [5, 50]]}, "geofence.polygon",
     "home (0, 0) is not inside the geofence"),
    ({"polygon": [[-20, -20], [70, -20], [70, 30], [-20, 30]]}, "waypoints.1",
     "is not inside the geofence"),
    ({**DEMO_FENCE, "margin": 12}, "waypoints.1", "is not at least 12 m inside"),
    ({"polygon": [[-20, -20], [60, -20], [60, 15], [30, 15], [30, 25], [60, 25], [60, 60],
                  [-20, 60]]}, "waypoints.1", "straight leg from waypoint 0 leaves the geofence"),
    ({**DEMO_FENCE, "max_altitude": 32}, "waypoints.1",
     "not 2 m under geofence.max_altitude (32 m), which the autopilot enforces"),
    ({**DEMO_FENCE, "max_altitude": 121}, "landing.failsafe_altitude",
     "120 m (the cap of the clear altitude) is not 2 m under geofence.max_altitude (121 m), "
     "which the autopilot enforces (geofence.upload): a climb's overshoot would breach it"),
    ({**DEMO_FENCE, "max_altitude": 100, "upload": False}, "landing.failsafe_altitude",
     "120 m (the cap of the clear altitude) is above geofence.max_altitude (100 m)"),
    ({**DEMO_FENCE, "margn": 3}, "geofence.margn", "did you mean margin"),
])
@pytest.mark.parametrize("command", ["validate", "fly"])
def test_a_bad_geofence_is_one_line_naming_the_field_and_exit_2(
        tmp_path, capsys, command, fence, field, reason):
    path = _demo_with(tmp_path, geofence=fence)
    args = [command, path] + (["--out", str(tmp_path / "out")] if command == "fly" else [])
    assert main(args) == 2
    line = _error(capsys)
    assert f": {field}: " in line and reason in line, line
    assert not (tmp_path / "out").exists()


def test_cruise_altitude_above_the_ceiling_is_named(tmp_path, capsys):
    path = _demo_with(tmp_path, geofence={**DEMO_FENCE, "max_altitude": 34},
                      waypoints=[[40.0, 0.0, 30.0]])
    assert main(["validate", path]) == 2
    assert ": cruise_altitude: 35 m is not 2 m under geofence.max_altitude (34 m)" \
        in _error(capsys)


def test_lat_lon_vertices_are_converted_about_home(tmp_path, capsys):
    # About 40 m west/south to 50 m east/north of the demo's home (47.397742, 8.545594).
    polygon = [{"lat": 47.39738, "lon": 8.54507}, {"lat": 47.39738, "lon": 8.54653},
               {"lat": 47.39830, "lon": 8.54653}, {"lat": 47.39830, "lon": 8.54507}]
    path = _demo_with(tmp_path, geofence={"polygon": polygon})
    assert main(["validate", path]) == 0
    area = load_mission(path).operating_area()
    x, y = np.asarray(area.vertices).T
    assert -45 < x.min() < -35 and 65 < x.max() < 75 and -45 < y.min() < -35



@pytest.mark.parametrize(("upload", "restore", "who"), [
    (True, True, "uploaded to the autopilot before takeoff, which enforces it too; the "
     "vehicle's own fence put back after landing"),
    (True, False, "uploaded to the autopilot before takeoff, which enforces it too; left on "
     "the vehicle after landing (geofence.restore: false)"),
    (False, True, "kept by this software only (geofence.upload: false)")])
def test_lander_validate_says_what_keeps_the_area(tmp_path, capsys, upload, restore, who):
    path = _demo_with(tmp_path, geofence={**DEMO_FENCE, "upload": upload, "restore": restore})
    assert main(["validate", path]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == f"geofence: 4 vertices, margin 2 m, ceiling 122 m above home; {who}"
