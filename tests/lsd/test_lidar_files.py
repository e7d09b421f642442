"""``lander detect --lidar`` on LAS/LAZ files: LAZ out of the box, the file's CRS and units,
sites in the file's CRS and as WGS84 lat/lon (sites.csv, sites.geojson), streamed tiles
equal to the whole cloud, and one clear line for bad input (issue 16)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from lsd.io import read_point_cloud, write_las
from lsd.lidar_pca.scenes import scene
from tests.lsd.detect_cli import lander, only_detect  # noqa: F401 - only_detect is autouse

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
US_FOOT = 1200.0 / 3937.0  # metres
# The same Lambert projection (North Carolina State Plane, NAD83) in metres and in US feet.
NC_METRES, NC_FEET = "EPSG:32119", "EPSG:2264"
NC_ORIGIN = np.array([600_000.0, 200_000.0, 100.0])  # metres, inside the state


def read_sites(out):
    with open(out / "sites.csv") as f:
        return list(csv.DictReader(f))


def test_laz_reads_out_of_the_box_with_its_crs_and_feet_to_metres():
    data = read_point_cloud(REAL / "autzen_suburban_ft.laz")
    assert len(data.points) == 110_000
    assert data.georef.unit_name == "foot" and data.georef.horizontal_unit == 0.3048
    import laspy

    header = laspy.open(REAL / "autzen_suburban_ft.laz").header
    np.testing.assert_allclose(data.points.max(0) - data.points.min(0),
                               (header.maxs - header.mins) * 0.3048, rtol=1e-9)


def test_sites_in_the_files_crs_and_as_wgs84(tmp_path, capsys):
    from pyproj import Transformer

    out = tmp_path / "o"
    # The patch's one clear ground (its north-west corner) holds a site only a little away
    # from the patch's edge: 3 m grid cells miss it, 2000 random search points find it.
    assert lander("--lidar", REAL / "nebraska_urban_ftus.las", "--seeding", "random",
                  "--n-points", 2000, "--out", out) == 0
    text = capsys.readouterr().out
    assert "EPSG:6880" in text and "US survey foot to metres" in text
    rows = read_sites(out)
    assert rows
    import laspy

    header = laspy.open(REAL / "nebraska_urban_ftus.las").header
    to_wgs84 = Transformer.from_crs("EPSG:6880", "EPSG:4326", always_xy=True)
    features = json.loads((out / "sites.geojson").read_text())["features"]
    assert len(features) == len(rows)
    for row, feature in zip(rows, features, strict=True):
        x, y = float(row["x"]), float(row["y"])  # US survey feet, the file's own frame
        assert header.mins[0] <= x <= header.maxs[0] and header.mins[1] <= y <= header.maxs[1]
        lon, lat = to_wgs84.transform(x, y)
        assert float(row["lon"]) == pytest.approx(lon, abs=1e-7)
        assert float(row["lat"]) == pytest.approx(lat, abs=1e-7)
        assert feature["geometry"]["coordinates"] == pytest.approx([lon, lat], abs=1e-7)


def test_a_feet_file_gives_the_sites_of_its_metre_conversion(tmp_path):
    points, codes = scene("urban", size=40.0, seed=3)
    feet = (points + NC_ORIGIN) / US_FOOT
    write_las(tmp_path / "ft.laz", feet, codes, NC_FEET, scale=0.001)
    # The metre conversion of exactly the points the feet file holds.
    stored = read_point_cloud(tmp_path / "ft.laz").points
    np.save(tmp_path / "m.npy", np.column_stack((stored, codes)))
    assert lander("--lidar", tmp_path / "ft.laz", "--out", tmp_path / "a") == 0
    assert lander("--lidar", tmp_path / "m.npy", "--out", tmp_path / "b") == 0
    a, b = read_sites(tmp_path / "a"), read_sites(tmp_path / "b")
    assert len(a) >= 3 and len(a) == len(b)
    for ra, rb in zip(a, b, strict=True):
        assert float(ra["x"]) * US_FOOT == pytest.approx(float(rb["x"]), abs=2e-3)
        assert float(ra["y"]) * US_FOOT == pytest.approx(float(rb["y"]), abs=2e-3)
        assert float(ra["z"]) * US_FOOT == pytest.approx(float(rb["z"]), abs=2e-3)
        assert ra["size"] == rb["size"]  # metres in both


def test_streamed_tiles_give_the_sites_of_the_whole_cloud(tmp_path, capsys):
    points, codes = scene("urban", size=60.0, seed=4)
    write_las(tmp_path / "c.laz", points + NC_ORIGIN, codes, NC_METRES)
    assert lander("--lidar", tmp_path / "c.laz", "--out", tmp_path / "whole") == 0
    assert lander("--lidar", tmp_path / "c.laz", "--tile-size", 15, "--out",
                  tmp_path / "tiles") == 0
    assert "tiles" in capsys.readouterr().out
    whole, tiles = read_sites(tmp_path / "whole"), read_sites(tmp_path / "tiles")
    assert len(whole) >= 5
    # The same sites (the class column needs the whole cloud: filled only when it is read).
    assert [{k: v for k, v in r.items() if k != "class"} for r in whole] == [
        {k: v for k, v in r.items() if k != "class"} for r in tiles]


def write_with_withheld(path: Path, points, codes, withheld, point_format: int) -> None:
    """A LAS file (NC state plane, metres) whose ``withheld`` points carry the flag."""
    import laspy
    from pyproj import CRS

    header = laspy.LasHeader(point_format=point_format,
                             version="1.4" if point_format >= 6 else "1.2")
    header.scales, header.offsets = np.full(3, 0.001), np.floor(points.min(axis=0))
    header.add_crs(CRS.from_user_input(NC_METRES))
    las = laspy.LasData(header)
    las.x, las.y, las.z = points.T
    las.classification = codes.astype(np.uint8)
    las.withheld = withheld
    las.write(str(path))


@pytest.mark.parametrize("point_format", [3, 6])  # the flag in the class byte, in its flags
def test_points_flagged_withheld_are_not_used(tmp_path, capsys, point_format):
    """Withheld points are deleted (LAS 1.4 R15, 'Withheld'): a flat classified field whose
    stray returns 10 m up are flagged so has its sites; read as points, they block every
    site (whole cloud and streamed in tiles alike)."""
    ground = np.stack(np.meshgrid(np.arange(0, 30, 0.25), np.arange(0, 30, 0.25)), -1)
    ground = np.c_[ground.reshape(-1, 2), np.zeros(ground.size // 2)]
    stray = np.stack(np.meshgrid(np.arange(1, 30, 1.0), np.arange(1, 30, 1.0)), -1)
    stray = np.c_[stray.reshape(-1, 2), np.full(stray.size // 2, 10.0)]
    points = np.r_[ground, stray] + NC_ORIGIN
    codes = np.r_[np.full(len(ground), 2), np.full(len(stray), 2)]
    flagged = np.r_[np.zeros(len(ground), bool), np.ones(len(stray), bool)]
    write_with_withheld(tmp_path / "c.las", points, codes, flagged, point_format)
    write_with_withheld(tmp_path / "u.las", points, codes, np.zeros_like(flagged), point_format)
    assert lander("--lidar", tmp_path / "c.las", "--out", tmp_path / "whole") == 0
    assert f"({len(stray)} with NaN/inf or beyond 1e8 m dropped, {len(stray)} of them " \
        "flagged withheld (deleted))" in capsys.readouterr().out
    assert lander("--lidar", tmp_path / "c.las", "--tile-size", 12, "--out",
                  tmp_path / "tiles") == 0
    assert lander("--lidar", tmp_path / "u.las", "--out", tmp_path / "unflagged") == 0
    whole, tiles = read_sites(tmp_path / "whole"), read_sites(tmp_path / "tiles")
    assert len(whole) >= 4 and [{k: v for k, v in r.items() if k != "class"} for r in whole] \
        == [{k: v for k, v in r.items() if k != "class"} for r in tiles]
    assert read_sites(tmp_path / "unflagged") == []
    assert read_point_cloud(tmp_path / "c.las").withheld == len(stray)


def test_a_cloud_in_memory_searched_in_tiles_gives_the_sites_of_the_whole(tmp_path):
    points, codes = scene("urban", size=60.0, seed=7)
    np.save(tmp_path / "c.npy", np.column_stack((points, codes)))
    assert lander("--lidar", tmp_path / "c.npy", "--out", tmp_path / "whole") == 0
    assert lander("--lidar", tmp_path / "c.npy", "--tile-size", 12, "--out",
                  tmp_path / "tiles") == 0
    whole, tiles = read_sites(tmp_path / "whole"), read_sites(tmp_path / "tiles")
    assert len(whole) >= 3 and whole == tiles


def test_no_crs_is_said_in_one_line_and_taken_as_metres(tmp_path, capsys):
    points, codes = scene("bare", size=20.0, seed=5)
    write_las(tmp_path / "c.las", points, codes)
    assert lander("--lidar", tmp_path / "c.las", "--out", tmp_path / "o") == 0
    text = capsys.readouterr().out
    assert "c.las: no CRS; coordinates taken as metres" in text
    rows = read_sites(tmp_path / "o")
    assert rows and rows[0]["lat"] == "" and not (tmp_path / "o" / "sites.geojson").exists()



def local_tm(lat: float, lon: float):
    """A transverse Mercator (metres, scale 1) centred at ``lat, lon`` on WGS84."""
    from pyproj.crs import GeographicCRS, ProjectedCRS
    from pyproj.crs.coordinate_operation import TransverseMercatorConversion

    return ProjectedCRS(TransverseMercatorConversion(lat, lon), geodetic_crs=GeographicCRS())


def write_degrees_and_metres(tmp_path, crs="EPSG:4326"):
    """A classified scene as LAS in lon/lat degrees (1e-7 deg, about a centimetre) and the
    same stored points projected by pyproj to metres in the transverse Mercator centred on
    the degrees file's extent (the detector's own frame, so the seeding grid is the same;
    UTM would not do: its 0.9996 scale and offset grid give other search points)."""
    import laspy
    from pyproj import Transformer

    points, codes = scene("urban", size=40.0, seed=3)
    lon, lat = Transformer.from_crs(local_tm(36.1, -81.0), "EPSG:4326",
                                    always_xy=True).transform(points[:, 0], points[:, 1])
    write_las(tmp_path / "deg.las", np.c_[lon, lat, points[:, 2] + 100.0], codes, crs,
              scale=1e-7)
    stored = laspy.read(tmp_path / "deg.las")
    centre = (stored.header.mins + stored.header.maxs) / 2
    metres = local_tm(centre[1], centre[0])
    x, y = Transformer.from_crs("EPSG:4326", metres, always_xy=True).transform(
        np.asarray(stored.x), np.asarray(stored.y))
    write_las(tmp_path / "m.las", np.c_[x, y, np.asarray(stored.z)], codes, metres,
              scale=1e-4)
    return metres


def test_a_degrees_file_gives_the_sites_of_its_projection_in_metres(tmp_path, capsys):
    from pyproj import Transformer

    metres = write_degrees_and_metres(tmp_path)
    assert lander("--lidar", tmp_path / "deg.las", "--out", tmp_path / "deg") == 0
    text = capsys.readouterr().out
    assert "CRS EPSG:4326: WGS 84, geographic (degrees): projected to a transverse " \
        "Mercator centred at 36.1" in text
    assert "deg.las: no vertical CRS; z taken as metres" in text
    assert "x, y in EPSG:4326 (lon, lat degrees), z in m" in text
    assert lander("--lidar", tmp_path / "m.las", "--out", tmp_path / "m") == 0
    deg, ref = read_sites(tmp_path / "deg"), read_sites(tmp_path / "m")
    assert len(deg) >= 3 and len(deg) == len(ref)
    to_wgs84 = Transformer.from_crs(metres, "EPSG:4326", always_xy=True)
    for d, r in zip(deg, ref, strict=True):
        lon, lat = to_wgs84.transform(float(r["x"]), float(r["y"]))
        # x, y are the file's lon/lat degrees; 3e-7 deg is about 3 cm.
        assert float(d["x"]) == pytest.approx(lon, abs=3e-7)
        assert float(d["y"]) == pytest.approx(lat, abs=3e-7)
        assert float(d["lon"]) == pytest.approx(float(r["lon"]), abs=3e-7)
        assert float(d["lat"]) == pytest.approx(float(r["lat"]), abs=3e-7)
        assert float(d["z"]) == pytest.approx(float(r["z"]), abs=0.02)
        assert d["size"] == r["size"]
    features = json.loads((tmp_path / "deg" / "sites.geojson").read_text())["features"]
    assert [f["geometry"]["coordinates"] for f in features] == [
        [float(d["lon"]), float(d["lat"])] for d in deg]


def test_a_degrees_file_streamed_in_tiles_and_judged(tmp_path, capsys):
    write_degrees_and_metres(tmp_path)
    assert lander("--lidar", tmp_path / "deg.las", "--judge", "--out", tmp_path / "whole") == 0
    assert "judge: sites" in capsys.readouterr().out
    assert lander("--lidar", tmp_path / "deg.las", "--tile-size", 12, "--out",
                  tmp_path / "tiles") == 0
    whole, tiles = read_sites(tmp_path / "whole"), read_sites(tmp_path / "tiles")
    assert len(whole) >= 3 and [{k: v for k, v in r.items() if k != "class"} for r in whole] \
        == [{k: v for k, v in r.items() if k != "class"} for r in tiles]


def test_a_compound_degrees_crs_gives_z_in_its_vertical_unit(tmp_path):
    """WGS 84 + NAVD88 height in US feet: z converted to metres, no note."""
    write_degrees_and_metres(tmp_path, "EPSG:4326+6360")
    data = read_point_cloud(tmp_path / "deg.las")
    assert data.georef.note is None
    assert data.georef.vertical_unit == pytest.approx(US_FOOT, rel=1e-12)
    heights = read_point_cloud(tmp_path / "m.las").points[:, 2]
    np.testing.assert_allclose(data.points[:, 2], heights * US_FOOT, atol=1e-4)


def bad_inputs(tmp_path):
    points, codes = scene("bare", size=20.0, seed=6)
    write_las(tmp_path / "good.laz", points, codes, NC_METRES)
    data = (tmp_path / "good.laz").read_bytes()
    (tmp_path / "truncated.laz").write_bytes(data[: len(data) // 2])
    (tmp_path / "text.las").write_text("x y z\n1 2 3\n")
    write_las(tmp_path / "empty.las", np.empty((0, 3)))
    np.save(tmp_path / "image.npy", np.ones((256, 256), dtype=np.float32))
    # Degrees too wide for one transverse Mercator (20 m read as 5 deg), or near a pole.
    write_las(tmp_path / "wide.las", np.c_[points[:, :2] * 0.25 + [-97, 41], points[:, 2]],
              codes, "EPSG:4326", scale=1e-7)
    write_las(tmp_path / "polar.las", np.c_[points[:, :2] * 1e-5 + [10, 88], points[:, 2]],
              codes, "EPSG:4326", scale=1e-7)
    return {
        "truncated.laz": "truncated.laz",
        "text.las": "not a readable LAS/LAZ file",
        "empty.las": "holds no points",
        "image.npy": "expected an (N, 3) array",
        "wide.las": "more than the 3 deg one transverse Mercator takes",
        "polar.las": "latitude beyond 85 deg",
    }


def test_bad_files_give_one_clear_line_and_exit_2(tmp_path, capsys):
    for name, words in bad_inputs(tmp_path).items():
        assert lander("--lidar", tmp_path / name, "--out", tmp_path / "o") == 2, name
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and words in err, (name, err)
        assert "Traceback" not in err
