"""A window of a large elevation model (``world.window``): a DEM tile as it is downloaded is
flown without cropping it first; only the window is read (``lander validate``, ``lander
terrain``, ``lander fly``), a window off the model is one line and exit 2."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")

from rasterio.transform import from_origin  # noqa: E402

from autonomy.cli import main  # noqa: E402
from sitl.terrain import make_terrain  # noqa: E402
from tests.sitl.test_geotiff import (  # noqa: E402
    REAL,
    line,
    plane,
    plateau_mission,
    srtm_tile,
    write_tif,
)
from tests.sitl.test_geotiff import validate_world as validate  # noqa: E402


def test_a_window_of_a_whole_srtm_tile_is_validated_reading_only_it(tmp_path, capsys):
    tile = srtm_tile(tmp_path)
    code, out, err = validate(tmp_path, capsys, f"path: {tile}, cell_size: 2.0, window: "
                              "{center: {lat: 36.5, lon: -84.5}, size: [2000, 3000]}")
    assert code == 0, err
    model = line(out, "elevation model: ")
    assert f"{tile}: 1209 x 1203 cells of 74.66 x 92.47 m (90188.4 x 111153 m)" in model
    assert "heights" not in model  # the tile was not read: only its window's heights are known
    window = line(out, "window: ")
    assert window.startswith("window: 2000 x 3000 m centred at lat 36.5, lon -84.5 (x 4508")
    read = window.split("), ")[1].split(" cells read")[0]
    nx, ny = (int(v) for v in read.split(" x "))
    assert nx * ny < 1000  # about 28 x 34 of the tile's 1.4 million cells
    # The tile's centre cell (600, 600) holds 0.3 * 600 + 0.1 * 600 = 240 m.
    low, high = (float(v) for v in window.split("heights ")[1].split(" m")[0].split(" .. "))
    assert 230 < low < 240 < high < 250


def test_a_window_of_a_huge_model_is_read_alone(tmp_path, capsys):
    """A 40,000 x 40,000 cell sparse tile (6.4 GB of float32 read whole): its 1 km window."""
    path = tmp_path / "huge.tif"
    with rasterio.open(path, "w", driver="GTiff", width=40_000, height=40_000, count=1,
                       dtype="float32", crs="EPSG:32617", tiled=True, sparse_ok=True,
                       transform=from_origin(500_000, 4_040_000, 1, 1)):
        pass
    tracemalloc.start()
    try:
        code, out, err = validate(tmp_path, capsys, f"path: {path}, cell_size: 1.0, "
                                  "window: {center: [30000, 12000], size: [1000, 1000]}")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert code == 0, err
    assert "40000 x 40000 cells of 1 x 1 m (39999 x 39999 m)" in line(out, "elevation model: ")
    assert "1001 x 1001 cells read, heights 0.00 .. 0.00 m" in line(out, "window: ")
    assert peak < 200e6, peak


@pytest.mark.parametrize(("window", "words"), [
    ("{center: {lat: 35.5, lon: -84.5}, size: [1000, 1000]}",
     "world.window.center: lat 35.5, lon -84.5 (x 4"),
    ("{center: [500, 90000], size: [2000, 2000]}",
     "world.window.size: a 2000 x 2000 m window centred at (500, 90000) reaches (-500, 90000)"),
], ids=["centre-off", "reaching-off"])
def test_a_window_off_the_model_is_refused_in_one_line(tmp_path, capsys, window, words):
    tile = srtm_tile(tmp_path)
    code, _, err = validate(tmp_path, capsys, f"path: {tile}, cell_size: 2.0, window: {window}")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert words in lines[0], lines[0]
    assert "off the elevation model (x 0 .. 90188" in lines[0] and "from its south-west corner" \
        in lines[0], lines[0]


def test_a_window_of_a_npy_model_is_cropped_and_home_is_on_the_window(tmp_path, capsys):
    """[x, y] metres from the model's south-west corner; home from the window's; a window
    given in degrees needs a model with a CRS."""
    np.save(tmp_path / "dem.npy", plane(101, 201, 1.0, 1.0)[::-1].copy())  # rows south first
    world = "path: dem.npy, source_cell_size: 1.0, cell_size: 0.5"
    code, out, err = validate(tmp_path, capsys, f"{world}, window: {{center: [120, 60], "
                              "size: [40, 20]}, home: [10, 5]", waypoint=(25, 10))
    assert code == 0, err
    assert line(out, "window: ").startswith(
        "window: 40 x 20 m centred at (x 120, y 60 m from the model's south-west corner), "
        "41 x 21 cells read, heights 35.00 .. 49.00 m")
    terrain = make_terrain({"kind": "file", "path": str(tmp_path / "dem.npy"),
                            "source_cell_size": 1.0, "cell_size": 0.5, "home_clear_radius": 0,
                            "window": {"center": [120, 60], "size": [40, 20]},
                            "home": [10, 5]}, seed=0)
    x, y = np.array([-10.0, 0.0, 29.5]), np.array([-5.0, 0.0, 14.5])
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=1e-4)
    code, _, err = validate(tmp_path, capsys, f"{world}, window: {{center: [120, 60], "
                            "size: [40, 20]}", waypoint=(25, 0))  # x 20 m is the window's edge
    assert code == 2 and "waypoints.0: (25, 0) is off the elevation model (x -20 .. 20" in err
    code, _, err = validate(tmp_path, capsys, f"{world}, window: {{center: {{lat: 36, "
                            "lon: -84}, size: [40, 20]}")
    assert code == 2 and "world.window.center: {lat, lon} needs a model with a coordinate" in err


def test_lander_terrain_builds_the_window_of_a_tile(tmp_path, capsys):
    tile = srtm_tile(tmp_path)
    assert main(["terrain", "--kind", "file", "--set", f"path={tile}", "--set", "cell_size=5",
                 "--set", "window={center: {lat: 36.25, lon: -84.75}, size: [3000, 2000]}",
                 "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"elevation model: {tile}: 1209 x 1203 cells of 74.66")
    assert out[1].startswith("window: 3000 x 2000 m centred at lat 36.25, lon -84.75 (x 2")
    assert out[2].startswith(f"note: {tile}: EPSG:4326 is geographic (degrees); reprojected")
    assert out[3].startswith("home: lat 36.2500000, lon -84.7500000 (x 1500, y 1000 m from "
                             "the window's south-west corner)")
    assert out[4].startswith("world file seed 0: 601 x 401 cells of 5 m, x -1500.0..1500.0 m, "
                             "y -1000.0..1000.0 m")


def test_a_flight_over_a_window_of_the_real_model_lands_on_it(tmp_path):
    """The plateau of the real SRTM model (near 540 m) as a 800 x 900 m window given by its
    latitude and longitude, flown by ``lander fly`` with the elevation-map detector."""
    with rasterio.open(REAL) as src:
        lon, lat = src.transform * (226, 104)  # the plateau's centre
    world = (f"{{kind: file, path: {REAL}, cell_size: 2.0, home_clear_radius: 3.0, "
             f"window: {{center: {{lat: {lat:.6f}, lon: {lon:.6f}}}, size: [800, 900]}}}}")
    mission = tmp_path / "plateau.yaml"
    mission.write_text(plateau_mission(world))
    out = tmp_path / "out"
    assert main(["fly", str(mission), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "landed" and summary["touchdown_safe"]
    touchdown = summary["touchdown"]
    terrain = make_terrain({"kind": "file", "path": str(REAL), "cell_size": 2.0,
                            "home_clear_radius": 3.0, "window": {
                                "center": {"lat": round(lat, 6), "lon": round(lon, 6)},
                                "size": [800, 900]}}, seed=0)
    assert terrain.extent == pytest.approx((-400, 400, -450, 450))
    assert terrain.has_ground(touchdown["x"], touchdown["y"])
    assert touchdown["z"] == pytest.approx(terrain.height(touchdown["x"], touchdown["y"]), abs=0.2)


def test_a_window_centred_in_degrees_on_a_utm_model_is_where_those_degrees_are(tmp_path,
                                                                              capsys):
    from pyproj import Transformer

    path = write_tif(tmp_path / "utm.tif", plane(401, 601, 2.0, 2.0),
                     from_origin(500_000, 4_000_800, 2.0, 2.0), "EPSG:32617")
    # (300, 200) m from the south-west cell's centre (500001, 3999999)
    lon, lat = Transformer.from_crs("EPSG:32617", "EPSG:4326", always_xy=True).transform(
        500_301, 4_000_199)
    window = f"{{center: {{lat: {lat!r}, lon: {lon!r}}}, size: [100, 60]}}"
    code, out, err = validate(tmp_path, capsys, f"path: {path}, cell_size: 0.5, "
                              f"window: {window}")
    assert code == 0, err
    assert "(x 300, y 200 m from the model's south-west corner), 51 x 31 cells read, " \
        "heights 92.00 .. 128.00 m" in line(out, "window: ")
    terrain = make_terrain({"kind": "file", "path": str(path), "cell_size": 0.5,
                            "home_clear_radius": 0, "window": {
                                "center": {"lat": lat, "lon": lon}, "size": [100, 60]}}, seed=0)
    x, y = np.array([-50.0, 0.0, 20.0]), np.array([-30.0, 0.0, 29.5])
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=1e-3)
