"""No-fly zones in the mission file (``geofence.exclude``): validated through ``lander
validate``, uploaded as exclusion polygons, kept out of by the flight, drawn and listed in
the report."""

from __future__ import annotations

import json
import math

import pytest
import yaml
from matplotlib.path import Path as PolygonPath

from autonomy.cli import main
from autonomy.cli.demo import mission_path
from autonomy.config import load_mission

DEMO = mission_path("demo.yaml")
AREA = [[-50, -50], [100, -50], [100, 100], [-50, 100]]
# Over (25, 55), where the demo lands without zones (its best site (8, 46) fails
# verification first); the demo's route (0,0) - (40,0) - (40,40) - (0,40) stays clear.
OVER_LANDING = [[15, 48], [35, 48], [35, 65], [15, 65]]


def _demo_with(tmp_path, exclude, **fence) -> str:
    data = yaml.safe_load(DEMO.read_text())
    data["geofence"] = {"polygon": AREA, "margin": 2, "exclude": exclude, **fence}
    path = tmp_path / "zoned.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return str(path)


def _error(capsys) -> str:
    (line,) = capsys.readouterr().err.strip().splitlines()
    return line


def test_a_demo_flight_lands_outside_a_no_fly_zone_over_its_usual_site(tmp_path):
    out = tmp_path / "out"
    assert main(["fly", _demo_with(tmp_path, [OVER_LANDING]), "--quiet",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "landed"
    touchdown = summary["touchdown"]
    assert not PolygonPath(OVER_LANDING).contains_point((touchdown["x"], touchdown["y"]))
    assert abs(touchdown["x"] - 55.0) < 2 and abs(touchdown["y"] - 20.0) < 2
    assert summary["lsm_counters"]["rejected_outside_geofence"] > 0
    assert summary["geofence_exclude"] == [OVER_LANDING]
    upload = summary["geofence_upload"]
    assert upload["no_fly_zones"] == 1 and "1 no-fly zone (exclusion polygons)" in upload["text"]
    assert (out / "report.png").stat().st_size > 0
    page = (out / "report.html").read_text()
    assert '"geofence_exclude":[[[15.0,48.0],[35.0,48.0]' in page.replace(" ", "")


WAYPOINT_ZONE = [[35, 30], [45, 30], [45, 50], [35, 50]]  # around waypoint 1 (40, 40)


@pytest.mark.parametrize(("exclude", "field", "reason"), [
    ([OVER_LANDING, WAYPOINT_ZONE], "waypoints.1",
     "(40.0, 40.0) is in the no-fly zone geofence.exclude.1 (or within its 2 m margin)"),
    ([[[15, 35], [25, 35], [25, 45], [15, 45]]], "waypoints.2",
     "the straight leg from waypoint 1 crosses the no-fly zone geofence.exclude.0 (or comes "
     "within its 2 m margin); add a waypoint to go round it"),
    ([[[-5, -5], [5, -5], [5, 5]]], "geofence.exclude.0",
     "home (0, 0) is in this no-fly zone (or within its 2 m margin)"),
    ([OVER_LANDING, [[200, 200], [210, 200], [210, 210]]], "geofence.exclude.1",
     "the no-fly zone lies outside geofence.polygon"),
    ([[[15, 48], [35, 65], [35, 48], [15, 65]]], "geofence.exclude.0",
     "not a simple polygon: edge 0 (vertices 0-1) meets edge 2 (vertices 2-3)"),
    ([[[15, 48], [16, 48], [17, 48]]], "geofence.exclude.0", "encloses no area"),
    ([[[15, 48], [16, 48]]], "geofence.exclude.0", "at least 3 items"),
    ([[[15, 48], [16, 48], "x"]], "geofence.exclude.0.2", "must be a list"),
])
def test_a_bad_no_fly_zone_is_one_line_naming_the_field_and_exit_2(
        tmp_path, capsys, exclude, field, reason):
    assert main(["validate", _demo_with(tmp_path, exclude)]) == 2
    line = _error(capsys)
    assert f": {field}: " in line and reason in line, line


def test_without_a_margin_a_waypoint_on_the_zone_edge_side_is_named_plainly(tmp_path, capsys):
    assert main(["validate", _demo_with(tmp_path, [WAYPOINT_ZONE], margin=0)]) == 2
    assert _error(capsys).endswith(
        ": waypoints.1: (40.0, 40.0) is in the no-fly zone geofence.exclude.0")


def test_lander_validate_counts_the_zones_and_lat_lon_zones_are_converted(tmp_path, capsys):
    # About 15..35 m east and 48..65 m north of the demo's home (47.397742, 8.545594).
    zone = [{"lat": 47.398174, "lon": 8.545793}, {"lat": 47.398174, "lon": 8.546059},
            {"lat": 47.398327, "lon": 8.546059}, {"lat": 47.398327, "lon": 8.545793}]
    path = _demo_with(tmp_path, [zone, OVER_LANDING])
    assert main(["validate", path]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith("geofence: 4 vertices, 2 no-fly zones, margin 2 m")
    area = load_mission(path).operating_area()
    (x0, y0), _, (x2, y2), _ = area.exclusions[0]
    assert x0 == pytest.approx(15, abs=0.5) and y0 == pytest.approx(48, abs=0.5)
    assert x2 == pytest.approx(35, abs=0.5) and y2 == pytest.approx(65, abs=0.5)


# A circle of 10 m about (25, 55), where the demo lands without zones (see OVER_LANDING).
CIRCLE_OVER_LANDING = {"centre": [25, 55], "radius": 10}


def test_a_demo_flight_lands_outside_a_no_fly_circle_over_its_usual_site(tmp_path):
    out = tmp_path / "out"
    assert main(["fly", _demo_with(tmp_path, [CIRCLE_OVER_LANDING]), "--quiet",
                 "--out", str(out)]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "landed"
    touchdown = summary["touchdown"]
    assert math.hypot(touchdown["x"] - 25, touchdown["y"] - 55) > 10 + 2
    assert summary["lsm_counters"]["rejected_outside_geofence"] > 0
    assert summary["geofence_exclude"] == [{"centre": [25.0, 55.0], "radius": 10.0}]
    upload = summary["geofence_upload"]
    assert upload["no_fly_circles"] == 1
    assert "1 no-fly zone (exclusion circles)" in upload["text"]
    assert (out / "report.png").stat().st_size > 0
    page = (out / "report.html").read_text().replace(" ", "")
    assert '"geofence_exclude":[{"centre":[25.0,55.0],"radius":10.0}]' in page


@pytest.mark.parametrize(("exclude", "field", "reason"), [
    ([OVER_LANDING, {"centre": [40, 38], "radius": 1}], "waypoints.1",
     "(40.0, 40.0) is in the no-fly zone geofence.exclude.1 (or within its 2 m margin)"),
    ([{"centre": [20, 44], "radius": 3}], "waypoints.2",
     "the straight leg from waypoint 1 crosses the no-fly zone geofence.exclude.0 (or comes "
     "within its 2 m margin); add a waypoint to go round it"),
    ([{"centre": [3, 3], "radius": 3}], "geofence.exclude.0",
     "home (0, 0) is in this no-fly zone (or within its 2 m margin)"),
    ([{"centre": [200, 200], "radius": 50}], "geofence.exclude.0",
     "the no-fly zone lies outside geofence.polygon"),
    ([OVER_LANDING, {"centre": [25, 55], "radius": 0}], "geofence.exclude.1.radius",
     "must be > 0"),
    ([{"centre": [25, 55], "radius": 60_000}], "geofence.exclude.0.radius",
     "must be <= 50000"),
    ([{"centre": [25, 55]}], "geofence.exclude.0.radius", "required"),
    ([{"centre": [25, 55], "radius": 5, "height": 3}], "geofence.exclude.0.height", ""),
    ([{"centre": "x", "radius": 5}], "geofence.exclude.0.centre", "must be a list"),
])
def test_a_bad_no_fly_circle_is_one_line_naming_the_field_and_exit_2(
        tmp_path, capsys, exclude, field, reason):
    assert main(["validate", _demo_with(tmp_path, exclude)]) == 2
    line = _error(capsys)
    assert f": {field}: " in line and reason in line, line


def test_a_lat_lon_circle_is_converted_and_counted(tmp_path, capsys):
    # About 25 m east and 55 m north of the demo's home (47.397742, 8.545594).
    circle = {"centre": {"lat": 47.398237, "lon": 8.545926}, "radius": 10}
    assert main(["validate", _demo_with(tmp_path, [OVER_LANDING, circle])]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1].startswith("geofence: 4 vertices, 2 no-fly zones, margin 2 m")
    zone = load_mission(_demo_with(tmp_path, [OVER_LANDING, circle])).operating_area(
    ).exclusions[1]
    assert (zone.x, zone.y, zone.radius) == pytest.approx((25, 55, 10), abs=0.5)
