"""GeoTIFF elevation models as real DEMs come: projected in metres or feet, geographic
(SRTM, Copernicus), int16 or float32 with nodata, non-square or south-up cells, through
``lander validate`` (what it says of the model, or one line and exit 2) and the terrain.

The real model is SRTM 3 arc-second data of the Jacksboro fault, Tennessee, that
matplotlib ships (tests/data/real/README.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")

from rasterio.transform import Affine, from_origin  # noqa: E402

from autonomy.cli import main  # noqa: E402
from sitl.terrain import make_terrain  # noqa: E402

REAL = Path(__file__).resolve().parents[1] / "data" / "real" / "jacksboro_srtm3_wgs84.tif"
US_FT = 1200 / 3937
FT = 0.3048


def write_tif(path: Path, north_up: np.ndarray, transform, crs, *, nodata=None, units=None,
              bands: np.ndarray | None = None, **options) -> Path:
    """A GeoTIFF of ``north_up`` (rows north to south, as GDAL writes them) or of the
    (count, ny, nx) ``bands``, with GDAL's creation ``options``."""
    data = north_up[None] if bands is None else bands
    with rasterio.open(path, "w", driver="GTiff", width=data.shape[2], height=data.shape[1],
                       count=data.shape[0], dtype=data.dtype, crs=crs, transform=transform,
                       nodata=nodata, **options) as dst:
        dst.write(data)
        if units:
            dst.units = (units,) * data.shape[0]
    return path


def plane(ny: int, nx: int, cell_x: float, cell_y: float, dtype="float32") -> np.ndarray:
    """Heights h = 0.3 x + 0.1 y (x, y and h in the file's own unit) from the south-west
    cell, rows north to south."""
    x = np.arange(nx)[None, :] * cell_x
    y = np.arange(ny)[::-1, None] * cell_y
    return (0.3 * x + 0.1 * y).astype(dtype)


def validate_world(tmp_path: Path, capsys, world: str, waypoint=(0, 0)) -> tuple[int, str, str]:
    mission = tmp_path / "m.yaml"
    mission.write_text(
        f"cruise_altitude: 20\nwaypoints:\n  - [{waypoint[0]}, {waypoint[1]}, 20]\n"
        "landing: {search_rectangle: [4, 4], pattern_center_radius: 1}\n"
        f"world: {{kind: file, home_clear_radius: 0, {world}}}\n"
    )
    code = main(["validate", str(mission)])
    captured = capsys.readouterr()
    assert "Traceback" not in captured.out + captured.err
    return code, captured.out, captured.err


def validate(tmp_path: Path, capsys, model: Path, cell_size=0.5) -> tuple[int, str, str]:
    return validate_world(tmp_path, capsys, f"path: {model}, cell_size: {cell_size}")


def srtm_tile(tmp_path: Path) -> Path:
    """N36W085.hgt as downloaded: one degree of 3 arc-second int16 heights
    h = 0.3 column + 0.1 row (from the south-west cell)."""
    import rasterio.shutil

    n, res = 1201, 1 / 1200
    write_tif(tmp_path / "tile.tif", plane(n, n, 1, 1, "int16"),
              from_origin(-85 - res / 2, 37 + res / 2, res, res), "EPSG:4326", nodata=-32768)
    path = tmp_path / "N36W085.hgt"
    rasterio.shutil.copy(tmp_path / "tile.tif", path, driver="SRTMHGT")
    return path


def refused(tmp_path: Path, capsys, model: Path) -> str:
    """The one error line of ``lander validate`` (exit 2) over ``model``."""
    code, _, err = validate(tmp_path, capsys, model)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1, err
    assert lines[0].startswith("lander validate: error: ") and f"cannot read {model}" in lines[0]
    return lines[0]


def line(out: str, start: str) -> str:
    """The line of ``out`` that starts with ``start``."""
    return next(s for s in out.splitlines() if s.startswith(start))


def model_line(out: str) -> str:
    return line(out, "elevation model: ")


def terrain_of(path: Path, **world):
    return make_terrain({"kind": "file", "path": str(path), "home_clear_radius": 0,
                         "cell_size": 0.5, **world}, seed=0)


def test_a_projected_model_in_metres_is_taken_as_it_is(tmp_path, capsys):
    path = write_tif(tmp_path / "utm.tif", plane(41, 61, 2.0, 2.0), from_origin(
        500_000, 4_000_080, 2.0, 2.0), "EPSG:32617", nodata=-9999.0)
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0
    assert "61 x 41 cells of 2 x 2 m (120 x 80 m), heights 0.00 .. 44.00 m" in model_line(out)
    assert "note:" not in out
    terrain = terrain_of(path)  # home at the centre (60, 40) m
    x, y = np.array([-50.0, 0.0, 33.3]), np.array([-30.0, 0.0, 17.1])
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=1e-3)


@pytest.mark.parametrize(("crs", "foot"), [("EPSG:2264", US_FT), ("EPSG:2222", FT)],
                         ids=["us-survey-feet", "international-feet"])
def test_a_model_in_feet_has_its_cells_and_heights_in_metres(tmp_path, capsys, crs, foot):
    """A state plane in feet: heights in feet too (no vertical CRS, as LAS has it)."""
    path = write_tif(tmp_path / "ft.tif", plane(41, 61, 3.0, 3.0),
                     from_origin(2_000_000, 600_000, 3.0, 3.0), crs)
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0
    cell, width, depth, top = 3 * foot, 180 * foot, 120 * foot, 66 * foot
    assert (f"61 x 41 cells of {cell:.4g} x {cell:.4g} m ({width:.6g} x {depth:.6g} m), "
            f"heights 0.00 .. {top:.2f} m") in model_line(out)
    assert "no vertical CRS; heights taken in the unit of x and y" in out
    terrain = terrain_of(path)
    x, y = np.array([-20.0, 0.0, 25.0]), np.array([-15.0, 0.0, 12.0])
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=1e-3)


def test_lander_terrain_says_how_a_model_in_feet_was_read(tmp_path, capsys):
    path = write_tif(tmp_path / "ft.tif", plane(41, 61, 3.0, 3.0),
                     from_origin(2_000_000, 600_000, 3.0, 3.0), "EPSG:2264")
    assert main(["terrain", "--kind", "file", "--set", f"path={path}", "--set",
                 "cell_size=0.5", "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"elevation model: {path}: 61 x 41 cells of 0.9144 x 0.9144 m")
    assert out[1] == (f"note: {path}: no vertical CRS; heights taken in the unit of x and y "
                      "(US survey foot)")
    # Home at the centre, 90 x 60 US ft from the south-west cell, in metres; 33 ft high.
    assert out[2].startswith("home: lat 35.39") and out[2].endswith(
        "(x 27.4321, y 18.288 m from the model's south-west corner), ground 10.06 m")
    assert out[3].startswith("world file seed 0: 110 x 74 cells of 0.5 m")


def test_heights_take_the_vertical_crs_unit_over_that_of_x_and_y(tmp_path, capsys):
    """UTM metres with NAVD88 heights in US survey feet (a compound CRS)."""
    path = write_tif(tmp_path / "cmpd.tif", np.full((5, 5), 1000, "float32"),
                     from_origin(500_000, 4_000_000, 10.0, 10.0), "EPSG:32617+6360")
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and f"cells of 10 x 10 m (40 x 40 m), heights {1000 * US_FT:.2f} .. " in out


def test_the_band_unit_gives_the_heights_unit_without_a_vertical_crs(tmp_path, capsys):
    path = write_tif(tmp_path / "ftband.tif", np.full((5, 5), 100, "float32"),
                     from_origin(500_000, 4_000_000, 10.0, 10.0), "EPSG:32617", units="ft")
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and f"heights {100 * FT:.2f} .. {100 * FT:.2f} m" in out
    odd = write_tif(tmp_path / "odd.tif", np.full((5, 5), 100, "float32"),
                    from_origin(500_000, 4_000_000, 10.0, 10.0), "EPSG:32617", units="asl")
    code, out, _ = validate(tmp_path, capsys, odd)
    assert code == 0 and "heights 100.00 .. 100.00 m" in out
    assert f"note: {odd}: band unit 'asl' is not a unit of length pyproj knows; ignored" in out


def test_the_real_model_holds_matplotlibs_srtm_heights_unchanged():
    from matplotlib import cbook

    with np.load(cbook.get_sample_data("jacksboro_fault_dem.npz", asfileobj=False)) as dem:
        heights, west, north = dem["elevation"], float(dem["xmin"]), float(dem["ymin"])
    with rasterio.open(REAL) as src:
        assert src.crs.to_epsg() == 4326 and src.dtypes[0] == "int16" and src.nodata == -32768
        assert src.transform.almost_equals(from_origin(west, north, 1 / 1200, 1 / 1200))
        np.testing.assert_array_equal(src.read(1), heights)


def test_the_real_srtm_model_in_degrees_is_reprojected_to_metres(tmp_path, capsys):
    """3 arc-seconds at 36.6 deg N: 74.6 m east-west, 92.5 m north-south; never degrees."""
    code, out, _ = validate(tmp_path, capsys, REAL, cell_size=5.0)
    assert code == 0
    line = model_line(out)
    assert "cells of 74.57 x 92.47 m" in line and "heights 241.25 .. 1073.11 m" in line, line
    width, depth = (float(v) for v in line.split("(")[1].split(" m)")[0].split(" x "))
    assert abs(width - 30_050) < 150 and abs(depth - 31_800) < 150  # the 0.336 x 0.287 deg
    assert "EPSG:4326 is geographic (degrees); reprojected to a transverse Mercator" in out


def test_the_other_dem_formats_gdal_reads_give_the_geotiffs_model(tmp_path, capsys):
    """ERDAS Imagine (.img) and a GDAL mosaic (.vrt) of the same heights read as the GeoTIFF
    does; an SRTM tile (.hgt, as downloaded: one degree, int16) is read and reprojected, and
    too large for a world whole, which the refusal says in metres."""
    import rasterio.shutil

    tif = write_tif(tmp_path / "utm.tif", plane(41, 61, 2.0, 2.0), from_origin(
        500_000, 4_000_080, 2.0, 2.0), "EPSG:32617", nodata=-9999.0)
    expected = model_line(validate(tmp_path, capsys, tif)[1])
    rasterio.shutil.copy(tif, tmp_path / "utm.img", driver="HFA")
    (tmp_path / "utm.vrt").write_text(
        '<VRTDataset rasterXSize="61" rasterYSize="41">'
        "<VRTRasterBand dataType=\"Float32\" band=\"1\"><SimpleSource>"
        '<SourceFilename relativeToVRT="1">utm.tif</SourceFilename><SourceBand>1</SourceBand>'
        "</SimpleSource></VRTRasterBand></VRTDataset>"
    )
    with rasterio.open(tif) as src:  # the VRT takes its georeference from its source
        text = (tmp_path / "utm.vrt").read_text().replace(
            '<VRTRasterBand', f"<SRS>{src.crs.to_wkt()}</SRS><GeoTransform>"
            f"{', '.join(str(v) for v in src.transform.to_gdal())}</GeoTransform><VRTRasterBand")
        (tmp_path / "utm.vrt").write_text(text)
    for name in ("utm.img", "utm.vrt"):
        code, out, err = validate(tmp_path, capsys, tmp_path / name)
        assert code == 0, err
        assert model_line(out).split(": ", 2)[2] == expected.split(": ", 2)[2], name
    srtm_tile(tmp_path)
    code, _, err = validate(tmp_path, capsys, tmp_path / "N36W085.hgt", cell_size=5.0)
    assert code == 2 and "N36W085.hgt spans 90188" in err and "x 111153 m" in err, err


def test_the_real_model_reads_alike_in_degrees_and_in_utm(tmp_path):
    """The same ground whether the file is in degrees or was reprojected to UTM 17N
    beforehand (as gdalwarp -t_srs EPSG:32617 does): UTM's grid north is turned by the
    meridian convergence from the true north of the model read from degrees."""
    from pyproj import Proj
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    with rasterio.open(REAL) as src:
        t, w, h = calculate_default_transform(src.crs, "EPSG:32617", src.width, src.height,
                                              *src.bounds, resolution=30.0)
        utm = np.full((h, w), -9999.0, dtype="float32")
        reproject(rasterio.band(src, 1), utm, dst_transform=t, dst_crs="EPSG:32617",
                  dst_nodata=-9999.0, resampling=Resampling.bilinear)
        left, bottom, right, top = src.bounds
    lon, lat = (left + right) / 2, (bottom + top) / 2
    utm_path = write_tif(tmp_path / "utm.tif", utm, t, "EPSG:32617", nodata=-9999.0)
    # Only the 18 km square about each model's centre (home) that the samples below fall
    # in, turned or not, is read: a fifth of the work of reading the whole model.
    near_home = {"size": [18_000.0, 18_000.0]}
    degrees = terrain_of(REAL, cell_size=5.0, window=near_home)
    metres = terrain_of(utm_path, cell_size=5.0, window=near_home)
    turn = np.radians(Proj("EPSG:32617").get_factors(lon, lat).meridian_convergence)
    xs, ys = (v.ravel() for v in np.meshgrid(np.linspace(-8000, 8000, 9),
                                             np.linspace(-8000, 8000, 9)))
    a = degrees.height(xs, ys)
    b = metres.height(np.cos(turn) * xs - np.sin(turn) * ys, np.sin(turn) * xs + np.cos(turn) * ys)
    assert np.ptp(a) > 300  # hundreds of metres of relief, 75-90 m cells
    # Heights are about home, and the two homes (each model's centre) differ by a little.
    diff = a - b
    assert np.median(np.abs(diff - np.median(diff))) < 12.0


@pytest.mark.parametrize(("dtype", "nodata"), [("int16", -32768), ("float32", -9999.0),
                                               ("float32", np.nan)])
def test_nodata_cells_have_no_ground(tmp_path, capsys, dtype, nodata):
    heights = np.full((41, 41), 100, dtype=dtype)
    heights[5:16, 25:36] = nodata  # 10 m x 10 m in the north-east, centred (30, 30) m
    path = write_tif(tmp_path / "hole.tif", heights, from_origin(500_000, 4_000_040, 1.0, 1.0),
                     "EPSG:32617", nodata=nodata)
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and "heights 100.00 .. 100.00 m, 7.2% unknown" in model_line(out)
    terrain = terrain_of(path)  # home at (20, 20)
    assert terrain.has_ground(0.0, 0.0) and not terrain.has_ground(10.0, 10.0)
    assert terrain.height(-15.0, 0.0) == pytest.approx(0.0)  # heights are about home


def test_non_square_cells_keep_their_sizes(tmp_path, capsys):
    path = write_tif(tmp_path / "rect.tif", plane(31, 21, 2.0, 1.0),
                     from_origin(500_000, 4_000_030, 2.0, 1.0), "EPSG:32617")
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and "21 x 31 cells of 2 x 1 m (40 x 30 m)" in model_line(out)
    terrain = terrain_of(path)
    x, y = np.array([-18.0, 0.0, 7.5]), np.array([-14.0, 0.0, 11.0])
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=1e-3)


def test_a_south_up_model_reads_as_the_north_up_one(tmp_path):
    north_up = plane(21, 31, 1.0, 1.0)
    a = write_tif(tmp_path / "north.tif", north_up, from_origin(500_000, 4_000_020, 1.0, 1.0),
                  "EPSG:32617")
    south_up = Affine(1.0, 0.0, 500_000, 0.0, 1.0, 4_000_000)  # row 0 is the southern one
    b = write_tif(tmp_path / "south.tif", north_up[::-1].copy(), south_up, "EPSG:32617")
    xs, ys = np.meshgrid(np.linspace(-14, 14, 7), np.linspace(-9, 9, 5))
    np.testing.assert_allclose(terrain_of(a).height(xs, ys), terrain_of(b).height(xs, ys))
    np.testing.assert_allclose(terrain_of(b).height(xs, ys), 0.3 * xs + 0.1 * ys, atol=1e-3)


def test_a_web_mercator_model_is_reprojected_not_taken_as_metres(tmp_path, capsys):
    """EPSG:3857 'metres' are 1 / cos(lat) too long: 41 % at 45 deg."""
    path = write_tif(tmp_path / "merc.tif", np.full((11, 11), 50, "float32"),
                     from_origin(-9_000_000, 5_621_521, 10.0, 10.0), "EPSG:3857")
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and "EPSG:3857 is scale off by 41% at the model; reprojected" in out
    cell = float(model_line(out).split("cells of ")[1].split(" x ")[0])
    assert cell == pytest.approx(10 * np.cos(np.radians(45.0)), rel=0.01)


def test_heights_with_an_alpha_band_use_it_as_their_mask(tmp_path, capsys):
    heights = np.full((2, 21, 21), 7, dtype="uint8")
    heights[1] = 255
    heights[1, :5, :5] = 0  # transparent corner: no ground there
    path = write_tif(tmp_path / "alpha.tif", None, from_origin(500_000, 4_000_020, 1.0, 1.0),
                     "EPSG:32617", bands=heights, alpha="YES")
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and "heights 7.00 .. 7.00 m, 5.7% unknown" in model_line(out)


def test_a_model_without_crs_is_taken_as_metres_and_says_so(tmp_path, capsys):
    path = write_tif(tmp_path / "local.tif", plane(11, 11, 1.0, 1.0),
                     from_origin(0, 10, 1.0, 1.0), None)
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and "11 x 11 cells of 1 x 1 m" in out
    assert f"note: {path}: no CRS; cells taken as metres, heights too" in out
    feet = write_tif(tmp_path / "local_ft.tif", np.full((11, 11), 10, "float32"),
                     from_origin(0, 10, 1.0, 1.0), None, units="ft")
    code, out, _ = validate(tmp_path, capsys, feet)
    assert code == 0 and f"heights {10 * FT:.2f} .. " in out
    assert f"note: {feet}: no CRS; cells taken as metres\n" in out


def test_a_local_grid_crs_in_feet_is_taken_as_a_level_grid_in_feet(tmp_path, capsys):
    """LOCAL_CS, as some LiDAR software writes for a site grid: its unit still holds."""
    from rasterio.crs import CRS

    local = CRS.from_wkt('LOCAL_CS["site grid",UNIT["US survey foot",0.304800609601219],'
                         'AXIS["Easting",EAST],AXIS["Northing",NORTH]]')
    path = write_tif(tmp_path / "site.tif", np.full((41, 41), 10, "float32"),
                     from_origin(0, 40, 1.0, 1.0), local)
    code, out, _ = validate(tmp_path, capsys, path)
    assert code == 0 and f"cells of {US_FT:.4g} x {US_FT:.4g} m" in out
    assert f"heights {10 * US_FT:.2f} .. " in out
    assert "local CRS 'site grid'; taken as a level grid in its unit (US survey foot)" in out


def _rgb(tmp_path):
    return write_tif(tmp_path / "photo.tif", None, from_origin(500_000, 4_000_008, 1, 1),
                     "EPSG:32617", bands=np.zeros((3, 8, 8), dtype="uint8"), photometric="RGB")


def _two_bands(tmp_path):
    return write_tif(tmp_path / "two.tif", None, from_origin(500_000, 4_000_008, 1, 1),
                     "EPSG:32617", bands=np.zeros((2, 8, 8), dtype="float32"))


def _rotated(tmp_path):
    t = Affine.translation(500_000, 4_000_000) * Affine.rotation(10) * Affine.scale(1, -1)
    return write_tif(tmp_path / "rotated.tif", np.zeros((8, 8), "float32"), t, "EPSG:32617")


def _plain_tiff(tmp_path):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # rasterio: not georeferenced, which is the point
        return write_tif(tmp_path / "plain.tif", np.zeros((8, 8), "float32"),
                         Affine.identity(), None)


def _not_a_tiff(tmp_path):
    path = tmp_path / "notes.tif"
    path.write_text("elevation: 120 m\n")
    return path


def _truncated(tmp_path):
    whole = write_tif(tmp_path / "whole.tif", np.zeros((200, 200), "float32"),
                      from_origin(500_000, 4_000_200, 1, 1), "EPSG:32617")
    path = tmp_path / "cut.tif"
    path.write_bytes(whole.read_bytes()[:60_000])
    return path


def _geocentric(tmp_path):
    return write_tif(tmp_path / "ecef.tif", np.zeros((8, 8), "float32"),
                     from_origin(0, 8, 1, 1), "EPSG:4978")


def _huge(tmp_path):
    # 8001 x 8001 cells with no block written (GDAL's sparse files): a few kB on disk, the
    # size of a national 1 m tile once read. Refused from the header, before any is read.
    path = tmp_path / "huge.tif"
    with rasterio.open(path, "w", driver="GTiff", width=8001, height=8001, count=1,
                       dtype="float32", crs="EPSG:32617", tiled=True, sparse_ok=True,
                       transform=from_origin(500_000, 4_008_001, 1, 1)):
        pass
    assert path.stat().st_size < 1_000_000
    return path


@pytest.mark.parametrize(("make", "words"), [
    (_rgb, "an image (red, green, blue bands), not an elevation model"),
    (_two_bands, "2 bands (gray, undefined): an elevation model has one band of heights; "
                 "write that band alone (gdal_translate -b N)"),
    (_rotated, "rotated or sheared geotransform"),
    (_plain_tiff, "not georeferenced (no geotransform)"),
    (_not_a_tiff, "not a GeoTIFF"),
    (_truncated, "damaged or truncated GeoTIFF"),
    (_geocentric, "CRS 'WGS 84' is geocentric, not a map of heights"),
    (_huge, "8001 x 8001 cells, more than the 64,000,000 a world may hold (memory)"),
], ids=["rgb-image", "two-bands", "rotated", "plain-tiff", "not-a-tiff", "truncated",
        "geocentric", "huge"])
def test_a_file_that_is_no_usable_model_is_refused_in_one_line(tmp_path, capsys, make, words):
    path = make(tmp_path)
    line = refused(tmp_path, capsys, path)
    assert words in line, line


def plateau_mission(world: str) -> str:
    """A short flight over a real model's plateau (``world``: the mission's world, inline
    YAML): one waypoint 30 m east, a small camera and a coarse map so that it takes seconds."""
    return f"""\
cruise_altitude: 30.0
waypoints:
  - [30.0, 0.0, 30.0]
landing: {{verification_duration: 6.0, search_rectangle: [40, 40], pattern_center_radius: 10}}
world: {world}
lsm: {{match_radius: 3.0}}
sitl: {{arming_settle_time: 2.0}}
perception:
  detector: elevation_map
  rate: 1.0
  camera: {{width: 64, height: 64, focal_px: 32.0}}
  elevation_map: {{size: 40.0, resolution: 1.0, fine_below: 0.0}}
seed: 3
"""


def test_a_flight_over_the_real_srtm_model_lands_on_it(tmp_path):
    """A 12 x 12 cell (0.9 km x 1 km) crop of the real model, still int16 in degrees with
    its nodata tag, flown by ``lander fly`` with the elevation-map detector."""
    import json

    from rasterio.windows import Window

    with rasterio.open(REAL) as src:
        window = Window(220, 98, 12, 12)  # a plateau near 540 m, 19 m of relief
        profile = {**src.profile, "width": 12, "height": 12,
                   "transform": src.window_transform(window)}
        crop = src.read(1, window=window)
    model = tmp_path / "plateau.tif"
    with rasterio.open(model, "w", **profile) as dst:
        dst.write(crop, 1)
    mission = tmp_path / "plateau.yaml"
    mission.write_text(plateau_mission(
        f"{{kind: file, path: {model}, cell_size: 2.0, home_clear_radius: 3.0}}"))
    out = tmp_path / "out"
    assert main(["fly", str(mission), "--out", str(out), "--quiet"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "landed" and summary["touchdown_safe"]
    touchdown = summary["touchdown"]
    terrain = terrain_of(model, cell_size=2.0)
    assert terrain.has_ground(touchdown["x"], touchdown["y"])
    assert touchdown["z"] == pytest.approx(terrain.height(touchdown["x"], touchdown["y"]), abs=0.2)
