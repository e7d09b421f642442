"""Home on a georeferenced elevation model, and nodata values a model does not tag.

A mission over a model with a coordinate system flies where the model is on the Earth: its
``home`` (lat, lon) is placed on the model, or, without one, the mission's home is the
model's position and ground height at the world's home; ``world.home`` may be given in
degrees. So the simulator's GPS, lat/lon waypoints and the ground under the vehicle agree.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")

from pymavlink import mavutil  # noqa: E402
from pyproj import Transformer  # noqa: E402
from rasterio.transform import from_origin  # noqa: E402

from autonomy.cli import main  # noqa: E402
from autonomy.config import load_mission  # noqa: E402
from sitl.terrain import make_terrain  # noqa: E402
from tests.sitl.test_geotiff import (  # noqa: E402
    REAL,
    line,
    model_line,
    plane,
    plateau_mission,
    validate,
    write_tif,
)

UTM_TO_WGS84 = Transformer.from_crs("EPSG:32617", "EPSG:4326", always_xy=True)


def utm_plane(tmp_path: Path) -> Path:
    """A 1200 x 800 m model in UTM 17N, h = 0.3 x + 0.1 y from its south-west cell's centre
    (500001, 3999999)."""
    return write_tif(tmp_path / "utm.tif", plane(401, 601, 2.0, 2.0),
                     from_origin(500_000, 4_000_800, 2.0, 2.0), "EPSG:32617")


def mission_file(tmp_path: Path, world: str, home: str = "") -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(
        (f"home: {home}\n" if home else "")
        + "cruise_altitude: 20\nwaypoints:\n  - [0, 0, 20]\n"
        "landing: {search_rectangle: [4, 4], pattern_center_radius: 1}\n"
        f"world: {{kind: file, home_clear_radius: 0, cell_size: 0.5, {world}}}\n"
    )
    return path


def run_validate(capsys, mission: Path) -> tuple[int, str, str]:
    code = main(["validate", str(mission)])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err
    return code, captured.out, captured.err


def test_world_home_in_degrees_is_where_those_degrees_are_on_the_model(tmp_path, capsys):
    path = utm_plane(tmp_path)
    lon, lat = UTM_TO_WGS84.transform(500_301, 4_000_199)  # (300, 200) m on the model
    code, out, err = validate(tmp_path, capsys, f"{path}, home: {{lat: {lat!r}, lon: {lon!r}}}")
    assert code == 0, err
    assert f"home: lat {lat:.7f}, lon {lon:.7f} (x 300, y 200 m from the model's south-west " \
        "corner), ground 110.00 m" == line(out, "home: ")
    terrain = make_terrain({"kind": "file", "path": str(path), "cell_size": 0.5,
                            "home_clear_radius": 0, "home": {"lat": lat, "lon": lon}}, seed=0)
    x, y = np.array([-300.0, 0.0, 250.0]), np.array([-200.0, 0.0, 150.0])
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=1e-3)
    assert terrain.extent == pytest.approx((-300, 900, -200, 600))


def test_a_missions_home_is_placed_on_a_georeferenced_model(tmp_path, capsys):
    path = utm_plane(tmp_path)
    lon, lat = UTM_TO_WGS84.transform(500_901, 4_000_599)  # (900, 600) m on the model
    mission = mission_file(tmp_path, f"path: {path}", f"{{lat: {lat!r}, lon: {lon!r}, alt: 200}}")
    code, out, err = run_validate(capsys, mission)
    assert code == 0, err
    assert "(x 900, y 600 m from the model's south-west corner), ground 330.00 m" \
        in line(out, "home: ")
    loaded = load_mission(mission)
    assert (loaded.home.lat, loaded.home.lon, loaded.home.alt) == (lat, lon, 200)
    terrain = make_terrain(loaded.world, seed=0)
    assert terrain.extent == pytest.approx((-900, 300, -600, 200))
    assert terrain.height(-900.0, -600.0) == pytest.approx(-330.0, abs=1e-3)


def test_without_a_home_the_mission_is_where_the_model_is(tmp_path):
    path = utm_plane(tmp_path)
    loaded = load_mission(mission_file(tmp_path, f"path: {path}"))
    lon, lat = UTM_TO_WGS84.transform(500_601, 4_000_399)  # the model's centre (600, 400) m
    assert loaded.home.lat == pytest.approx(lat, abs=1e-9)
    assert loaded.home.lon == pytest.approx(lon, abs=1e-9)
    assert loaded.home.alt == pytest.approx(0.3 * 600 + 0.1 * 400)
    assert loaded.sitl.home == loaded.home  # the simulator's GPS says the same
    assert not loaded.has_home and loaded.home_source == "elevation model"


def test_a_flight_over_the_real_model_reports_the_models_position(tmp_path):
    """Without a home in the mission, the simulator's HOME_POSITION and GPS are the real
    SRTM model's latitude, longitude and ground height at the world's home."""
    with rasterio.open(REAL) as src:
        lon, lat = src.xy(104, 226)  # the plateau: the centre of row 104, column 226
        ground = float(src.read(1)[104, 226])
    world = (f"{{kind: file, path: {REAL}, cell_size: 2.0, home_clear_radius: 3.0, "
             f"window: {{center: {{lat: {lat:.6f}, lon: {lon:.6f}}}, size: [600, 600]}}}}")
    mission = tmp_path / "plateau.yaml"
    mission.write_text(plateau_mission(world) + "time_limit: 40\n")
    out = tmp_path / "out"
    main(["fly", str(mission), "--out", str(out), "--quiet"])
    tlog = mavutil.mavlink_connection(str(out / "flight.tlog"))
    home = tlog.recv_match(type="HOME_POSITION")
    assert home.latitude * 1e-7 == pytest.approx(lat, abs=2e-6)  # within 0.2 m
    assert home.longitude * 1e-7 == pytest.approx(lon, abs=2e-6)
    assert home.altitude * 1e-3 == pytest.approx(ground, abs=3.0)  # a cell's relief
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] != "crashed"


def test_a_missions_home_off_a_georeferenced_model_is_refused_in_one_line(tmp_path, capsys):
    mission = mission_file(tmp_path, f"path: {utm_plane(tmp_path)}",
                           "{lat: 47.397742, lon: 8.545594, alt: 488}")
    code, _, err = run_validate(capsys, mission)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert f"{mission}:1: home: lat 47.397742, lon 8.545594 is off the elevation model " \
        "utm.tif, which has a coordinate system: move home onto it, or give world.home" in err


def test_a_model_without_coordinates_keeps_home_at_its_centre(tmp_path, capsys):
    path = tmp_path / "flat.npy"
    np.save(path, np.zeros((41, 61)))
    world = f"path: {path}, source_cell_size: 1.0"
    mission = mission_file(tmp_path, world, "{lat: 47.397742, lon: 8.545594, alt: 488}")
    code, out, err = run_validate(capsys, mission)
    assert code == 0, err
    assert make_terrain(load_mission(mission).world, seed=0).extent == pytest.approx(
        (-30, 30, -20, 20))
    code, _, err = run_validate(capsys, mission_file(
        tmp_path, world + ", home: {lat: 47.4, lon: 8.5}"))
    assert code == 2 and "home: {lat, lon} needs a model with a coordinate system" in err


def asc_text(heights: np.ndarray) -> str:
    rows = "\n".join(" ".join(f"{v:g}" for v in row) for row in heights)
    return (f"ncols {heights.shape[1]}\nnrows {heights.shape[0]}\nxllcenter 0\nyllcenter 0\n"
            f"cellsize 1\n{rows}\n")


@pytest.mark.parametrize("kind", ["utm", "degrees", "asc", "npy"])
def test_an_untagged_nodata_value_is_unknown_once_named(tmp_path, capsys, kind):
    """-9999 in a model that does not tag it is a height of -9999 m, until the mission says
    ``world.nodata: -9999``; in degrees it is masked before the reprojection blends it."""
    heights = np.full((41, 41), 100, dtype="float32")
    heights[5:16, 25:36] = -9999  # 11 x 11 cells in the north-east
    world = {
        "utm": lambda: write_tif(tmp_path / "m.tif", heights, from_origin(
            500_000, 4_000_040, 1.0, 1.0), "EPSG:32617"),
        "degrees": lambda: write_tif(tmp_path / "m.tif", heights, from_origin(
            -84.3, 36.6, 1e-5, 1e-5), "EPSG:4326"),
        "asc": lambda: (tmp_path / "m.asc").write_text(asc_text(heights)) and tmp_path / "m.asc",
        "npy": lambda: np.save(tmp_path / "m.npy", heights[::-1]) or tmp_path / "m.npy",
    }[kind]()
    extra = ", source_cell_size: 1.0" if kind == "npy" else ""
    code, out, err = validate(tmp_path, capsys, f"{world}{extra}")
    assert code == 0, err
    assert "heights -9999.00 .. 100.00 m" in model_line(out)
    code, out, err = validate(tmp_path, capsys, f"{world}{extra}, nodata: -9999")
    assert code == 0, err
    said = model_line(out)
    assert "heights 100.00 .. 100.00 m, " in said and "% unknown" in said
