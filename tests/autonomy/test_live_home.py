"""Frames on a live vehicle: lat/lon waypoints are flown to their lat/lon about the home the
vehicle reports; a mission file whose home disagrees is refused unless told which to use."""

from __future__ import annotations

import json
import math
import threading
from pathlib import Path

import pytest
import yaml

from autonomy.cli import main
from autonomy.config import apply_overrides, geodetic_to_enu, load_mission
from autonomy.errors import UserError
from autonomy.runner.home import HomeMismatch, choose_home
from sitl.copter import HomeSettings
from sitl.copter.geo import LocalToGlobal

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"
FILE_HOME = (47.397742, 8.545594, 488.0)  # demo.yaml's home
VEHICLE_HOME = (47.398742, 8.545594, 488.0)  # 111 m north of it
# A lat/lon waypoint 30 m east and 20 m north of the vehicle's home.
TARGET = (VEHICLE_HOME[0] + 20.0 / 111_320.0, VEHICLE_HOME[1] + 30.0 / 75_460.0)


def write_mission(tmp_path: Path) -> Path:
    """demo.yaml flying one lat/lon waypoint, then landing at a scripted site near it."""
    data = load_mission(DEMO).source_data()
    data["waypoints"] = [{"lat": TARGET[0], "lon": TARGET[1], "alt": 12.0}]
    data["sites"] = [{"x": 33.0, "y": 24.0, "size": 5.0}]
    path = tmp_path / "geo.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def closest_approach(sitl, done: threading.Event, out: list[float]) -> None:
    """Track the simulator's truth, as lat/lon, against the commanded lat/lon (metres)."""
    to_global = LocalToGlobal(VEHICLE_HOME[0], VEHICLE_HOME[1])
    while not done.is_set():
        x, y, _ = sitl.truth.position
        lat, lon = to_global(x, y)
        east, north = geodetic_to_enu(lat, lon, TARGET[0], TARGET[1])
        out.append(math.hypot(east, north))
        done.wait(0.001)


def test_lat_lon_waypoints_are_flown_about_the_vehicles_home(served_sitl, tmp_path, capsys):
    served = served_sitl(speedup=10.0, home=HomeSettings(
        lat=VEHICLE_HOME[0], lon=VEHICLE_HOME[1], alt=VEHICLE_HOME[2]))
    mission = write_mission(tmp_path)
    args = ["fly", str(mission), "--connect", served.url, "--set",
            "landing.acceptance_radius=0.5"]

    refused = tmp_path / "refused"
    assert main([*args, "--out", str(refused)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "47.3987420, 8.5455940" in err[0] and "47.3977420, 8.5455940" in err[0]
    assert "111.2 m apart" in err[0] and "--home-from" in err[0]
    summary = json.loads((refused / "summary.json").read_text())
    assert (summary["outcome"], summary["exit_code"]) == ("refused", 2)
    assert not served.sitl.truth.armed, "refused before takeoff"

    distances: list[float] = []
    done = threading.Event()
    watch = threading.Thread(target=closest_approach, args=(served.sitl, done, distances),
                             daemon=True)
    watch.start()
    flown = tmp_path / "flown"
    try:
        code = main([*args, "--out", str(flown), "--home-from", "vehicle"])
    finally:
        done.set()
        watch.join(timeout=5)
    summary = json.loads((flown / "summary.json").read_text())
    assert (code, summary["outcome"]) == (3, "landed_unjudged")
    assert summary["home"]["used"] == "vehicle" and summary["home"]["agree"] is False
    assert min(distances) < 1.0
    out = capsys.readouterr().out
    assert "flying by the vehicle's home" in out
    assert "exit 3: landed and disarmed on a verified site; the ground was not judged" in out


def mission_with_home(home: tuple[float, float, float] | None, **overrides):
    mission = load_mission(DEMO)
    data = mission.source_data()
    if home is None:
        data.pop("home")
    else:
        data["home"] = {"lat": home[0], "lon": home[1], "alt": home[2]}
    data["waypoints"] = [{"lat": TARGET[0], "lon": TARGET[1], "alt": 20.0}]
    return apply_overrides(type(mission).model_validate(data), overrides)


def test_homes_within_the_tolerances_agree_and_the_vehicles_is_flown_by():
    near = (FILE_HOME[0] + 3.0 / 111_320.0, FILE_HOME[1], FILE_HOME[2] + 8.0)
    choice = choose_home(mission_with_home(FILE_HOME), near)
    assert choice.agree and choice.used == "vehicle" and choice.lat_lon == near[:2]
    with pytest.raises(HomeMismatch, match="tolerance 5 m, 10 m"):
        choose_home(mission_with_home(FILE_HOME), (near[0], near[1], FILE_HOME[2] + 12.0))
    looser = mission_with_home(FILE_HOME, **{"vehicle.home_altitude_tolerance": 15.0})
    assert choose_home(looser, (near[0], near[1], FILE_HOME[2] + 12.0)).agree


def test_home_from_file_flies_the_mission_as_drawn_about_the_files_home():
    mission = mission_with_home(FILE_HOME, **{"vehicle.home_from": "file"})
    choice = choose_home(mission, VEHICLE_HOME)
    assert choice.used == "file" and not choice.agree
    x, y, _ = mission.plan(home=choice.lat_lon).waypoints[0]
    # Offsets from the file's home: 111 m further north than the target is from the vehicle.
    assert x == pytest.approx(30.0, abs=0.2) and y == pytest.approx(131.2, abs=0.3)


def test_without_a_home_in_the_file_the_vehicles_is_used():
    mission = mission_with_home(None)
    choice = choose_home(mission, VEHICLE_HOME)
    assert choice.used == "vehicle" and choice.file is None
    x, y, _ = mission.plan(home=choice.lat_lon).waypoints[0]
    assert x == pytest.approx(30.0, abs=0.2) and y == pytest.approx(20.0, abs=0.2)
    with pytest.raises(UserError, match="gives no home"):
        choose_home(mission, VEHICLE_HOME, "file")


def test_a_home_taken_from_an_elevation_model_is_checked_like_a_files(tmp_path):
    """A mission over a georeferenced model without a ``home`` is where the model is: a
    vehicle whose home is elsewhere would see that ground under it, so it is refused until
    told which home to fly by, and one at the model's home agrees."""
    pytest.importorskip("rasterio")
    from tests.sitl.test_model_home import mission_file, utm_plane

    mission = load_mission(mission_file(tmp_path, f"path: {utm_plane(tmp_path)}"))
    model = (mission.home.lat, mission.home.lon, mission.home.alt)
    assert mission.home_source == "elevation model"
    north = (model[0] + 0.001, model[1], model[2])  # 111 m north of the model's home
    with pytest.raises(HomeMismatch, match=r"the elevation model's home \(utm.tif at "
                       r"world.home\) is .*: 111.0 m apart"):
        choose_home(mission, north)
    choice = choose_home(mission, (model[0] + 2.0 / 111_320.0, model[1], model[2] + 3.0))
    assert choice.agree and choice.file_source == "elevation model"
    assert choice.as_dict()["file"] == pytest.approx(model)


def test_a_live_flight_over_a_model_elsewhere_is_refused_before_takeoff(
        served_sitl, tmp_path, capsys):
    pytest.importorskip("rasterio")
    from tests.sitl.test_model_home import mission_file, utm_plane

    served = served_sitl(speedup=10.0, home=HomeSettings(
        lat=VEHICLE_HOME[0], lon=VEHICLE_HOME[1], alt=VEHICLE_HOME[2]))
    mission = mission_file(tmp_path, f"path: {utm_plane(tmp_path)}")
    out = tmp_path / "refused"
    assert main(["fly", str(mission), "--connect", served.url, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "the elevation model's home (utm.tif at world.home)" in err[0]
    assert "--home-from" in err[0]
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["outcome"], summary["exit_code"]) == ("refused", 2)
    assert not served.sitl.truth.armed, "refused before takeoff"


def box(east: tuple[float, float], north: tuple[float, float]) -> list[dict[str, float]]:
    """A lat/lon geofence: the box of ``east`` x ``north`` metres about the file's home."""
    lat = [FILE_HOME[0] + n / 111_320.0 for n in north]
    lon = [FILE_HOME[1] + e / 75_460.0 for e in east]
    return [{"lat": lat[0], "lon": lon[0]}, {"lat": lat[0], "lon": lon[1]},
            {"lat": lat[1], "lon": lon[1]}, {"lat": lat[1], "lon": lon[0]}]


def fenced_mission(tmp_path: Path, name: str, waypoints: list, polygon: list) -> Path:
    """demo.yaml in a geofence, cut short: one waypoint, a site under it, a short hover."""
    data = load_mission(DEMO).source_data()
    data.update(waypoints=waypoints, geofence={"polygon": polygon, "max_altitude": 30.0},
                cruise_altitude=10.0, sites=[{"x": 0.0, "y": 10.0, "size": 5.0}])
    data["landing"].update(verification_duration=1.0, failsafe_altitude=20.0,
                           search_rectangle=[10.0, 10.0])
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    return path


def fly_live(url: str, mission: Path, out: Path, capsys, *options: str) -> tuple[int, str, dict]:
    code = main(["fly", str(mission), "--connect", url, "--out", str(out), *options])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err
    return code, captured.err.strip(), json.loads((out / "summary.json").read_text())


def test_a_mission_outside_its_fence_about_the_vehicles_home_is_refused_before_takeoff(
        served_sitl, tmp_path, capsys):
    """ENU waypoints move with the home, a lat/lon fence stays on the Earth (and the other
    way round): flown by a vehicle's home 111 m north of the file's, a mission the file's
    check passed leaves its fence, and is refused as the file would be, naming the home."""
    served = served_sitl(speedup=10.0, home=HomeSettings(
        lat=VEHICLE_HOME[0], lon=VEHICLE_HOME[1], alt=VEHICLE_HOME[2]))
    # Both homes inside; [0, 10] north of the file's home is, of the vehicle's is not.
    enu_waypoints = fenced_mission(tmp_path, "enu", [[0.0, 10.0, 8.0]],
                                   box((-30.0, 30.0), (-30.0, 115.0)))
    code, err, summary = fly_live(served.url, enu_waypoints, tmp_path / "enu", capsys,
                                  "--home-from", "vehicle")
    assert (code, summary["outcome"], summary["exit_code"]) == (2, "refused", 2)
    assert err == ("lander fly: error: about the vehicle's home 47.398742, 8.545594: "
                   "waypoints.0: (0.0, 10.0) is not inside the geofence")
    # A lat/lon waypoint 10 m north of the file's home is 101 m south of the vehicle's,
    # out of an ENU fence drawn about home.
    lat_lon_waypoints = fenced_mission(
        tmp_path, "geo", [{"lat": FILE_HOME[0] + 10.0 / 111_320.0, "lon": FILE_HOME[1],
                           "alt": 8.0}], [[-30.0, -30.0], [30.0, -30.0], [30.0, 30.0],
                                          [-30.0, 30.0]])
    code, err, summary = fly_live(served.url, lat_lon_waypoints, tmp_path / "geo", capsys,
                                  "--home-from", "vehicle")
    assert (code, summary["outcome"]) == (2, "refused")
    assert err.startswith("lander fly: error: about the vehicle's home 47.398742, 8.545594: "
                          "waypoints.0: (0.0, -101.") and err.endswith(
        ") is not inside the geofence") and "\n" not in err
    assert not served.sitl.truth.armed, "refused before takeoff"


def test_the_same_mission_flies_where_the_homes_agree(served_sitl, tmp_path, capsys):
    served = served_sitl(speedup=20.0, home=HomeSettings(
        lat=FILE_HOME[0], lon=FILE_HOME[1], alt=FILE_HOME[2]))
    mission = fenced_mission(tmp_path, "enu", [[0.0, 10.0, 8.0]],
                             box((-30.0, 30.0), (-30.0, 115.0)))
    code, err, summary = fly_live(served.url, mission, tmp_path / "flown", capsys)
    assert (code, summary["outcome"]) == (3, "landed_unjudged"), err
    assert summary["home"]["agree"] is True
    assert summary["geofence_upload"]["text"].startswith("geofence uploaded")


def test_lat_lon_waypoints_about_a_distant_vehicles_home_must_stay_on_the_elevation_model(
        served_sitl, tmp_path, capsys):
    """The simulated ground lies about the home flown by: a lat/lon waypoint on the model
    about the file's home is off it about a vehicle's 1 km north."""
    pytest.importorskip("rasterio")
    from tests.sitl.test_model_home import mission_file, utm_plane

    path = mission_file(tmp_path, f"path: {utm_plane(tmp_path)}")
    home = load_mission(path).home
    data = yaml.safe_load(path.read_text())
    data["waypoints"] = [{"lat": home.lat, "lon": home.lon, "alt": 20.0}]
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    served = served_sitl(speedup=10.0, home=HomeSettings(
        lat=home.lat + 1000.0 / 111_000.0, lon=home.lon, alt=home.alt))
    code, err, summary = fly_live(served.url, path, tmp_path / "out", capsys,
                                  "--home-from", "vehicle")
    assert (code, summary["outcome"]) == (2, "refused")
    assert "about the vehicle's home" in err and "\n" not in err
    assert "waypoints.0: (-0.00413672, -1002.86) is off the elevation model" in err, err
    assert not served.sitl.truth.armed
