"""How an elevation model's file stores its heights and its place on the Earth, beyond a
plain GeoTIFF: heights stored as scaled integers (a band's scale and offset), and an ESRI
ASCII grid whose coordinate system is in a ``.prj`` file beside it (as GDAL and ESRI write
it). Each model must read as the same heights, at the same place, as the plain GeoTIFF of
the same ground; the files are written by GDAL (rasterio), the reader's oracle."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

rasterio = pytest.importorskip("rasterio")

from rasterio import shutil as gdal_files  # noqa: E402
from rasterio.crs import CRS  # noqa: E402
from rasterio.transform import from_origin  # noqa: E402

from tests.sitl.test_geotiff import (  # noqa: E402
    line,
    model_line,
    plane,
    terrain_of,
    validate,
    validate_world,
    write_tif,
)

UTM = from_origin(500_000, 4_000_080, 2.0, 2.0)  # 61 x 41 cells of 2 m, UTM 17N


def scaled_tif(tmp_path: Path, scale: float, offset: float, *, nodata=None) -> Path:
    """The plane h = 0.3 x + 0.1 y + 250 (metres) stored as int16 (h - offset) / scale."""
    heights = plane(41, 61, 2.0, 2.0, "float64") + 250.0
    stored = np.round((heights - offset) / scale).astype(np.int16)
    path = write_tif(tmp_path / "scaled.tif", stored, UTM, "EPSG:32617", nodata=nodata)
    with rasterio.open(path, "r+") as dst:
        dst.scales, dst.offsets = (scale,), (offset,)
    return path


def test_heights_stored_as_scaled_integers_are_read_in_metres(tmp_path, capsys):
    path = scaled_tif(tmp_path, 0.01, 200.0)  # centimetres above 200 m
    with rasterio.open(path) as src:  # GDAL's own unscaling, the oracle
        expected = src.read(1).astype(float) * src.scales[0] + src.offsets[0]
    code, out, err = validate(tmp_path, capsys, path)
    assert code == 0, err
    assert "heights 250.00 .. 294.00 m" in model_line(out)
    assert "note: " in out and "heights are the stored values x 0.01 + 200 (the band's " \
        "scale and offset)" in line(out, "note: ")
    terrain = terrain_of(path)  # home at the model's centre, (60, 40) m
    x, y = np.array([-50.0, 0.0, 33.0]), np.array([-30.0, 0.0, 17.0])
    centre = expected[20, 30]  # row 20 from the north, column 30: the centre cell
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=0.02)
    assert centre == pytest.approx(250.0 + 0.3 * 60 + 0.1 * 40, abs=0.01)


def test_an_untagged_nodata_value_is_the_stored_one_of_a_scaled_model(tmp_path, capsys):
    path = scaled_tif(tmp_path, 0.1, 0.0)
    with rasterio.open(path, "r+") as dst:  # a hole the file does not tag
        stored = dst.read(1)
        stored[:5, :5] = -9999
        dst.write(stored, 1)
    code, out, _ = validate_world(tmp_path, capsys, f"path: {path}, cell_size: 0.5")
    assert code == 0 and "heights -999.90 .. " in model_line(out)
    code, out, err = validate_world(tmp_path, capsys,
                                    f"path: {path}, cell_size: 0.5, nodata: -9999")
    assert code == 0, err
    assert "heights 250.00 .. 294.00 m" in model_line(out)


def test_a_band_scale_of_zero_is_refused_in_one_line(tmp_path, capsys):
    path = scaled_tif(tmp_path, 1.0, 0.0)
    with rasterio.open(path, "r+") as dst:
        dst.scales = (0.0,)
    code, _, err = validate(tmp_path, capsys, path)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "band 1 has scale 0 and offset 0: heights are stored value x scale + offset" in err


def ascii_grid(tmp_path: Path, tif: Path, name: str) -> Path:
    """``tif`` as an ESRI ASCII grid with its .prj beside it, written by GDAL."""
    path = tmp_path / f"{name}.asc"
    gdal_files.copy(tif, path, driver="AAIGrid")
    assert path.with_suffix(".prj").exists()
    return path


def test_an_ascii_grid_with_a_prj_is_placed_where_its_geotiff_is(tmp_path, capsys):
    """In UTM, and in degrees (reprojected): the same model, home and ground as the GeoTIFF
    of the same cells."""
    utm = write_tif(tmp_path / "utm.tif", plane(41, 61, 2.0, 2.0), UTM, "EPSG:32617")
    res = 1 / 1200
    degrees = write_tif(tmp_path / "deg.tif", plane(41, 61, 1, 1),
                        from_origin(-84.3, 36.6, res, res), "EPSG:4326")
    for tif, cell in ((utm, 0.5), (degrees, 5.0)):
        asc = ascii_grid(tmp_path, tif, tif.stem)
        code, want, err = validate(tmp_path, capsys, tif, cell)
        assert code == 0, err
        code, got, err = validate(tmp_path, capsys, asc, cell)
        assert code == 0, err
        assert model_line(got).split(": ", 2)[2] == model_line(want).split(": ", 2)[2]
        assert line(got, "home: ") == line(want, "home: ")
        assert line(got, "home: ").startswith("home: lat ")  # it has a place on the Earth


def test_a_malformed_ascii_grid_with_a_prj_is_named_by_its_line(tmp_path, capsys):
    asc = ascii_grid(tmp_path, write_tif(tmp_path / "utm.tif", plane(41, 61, 2.0, 2.0), UTM,
                                         "EPSG:32617"), "utm")
    lines = asc.read_text().splitlines()
    words = lines[9].split()
    lines[9] = " ".join(words[:3] + ["x7"] + words[4:])
    asc.write_text("\n".join(lines) + "\n")
    code, _, err = validate(tmp_path, capsys, asc)
    assert code == 2 and f"{asc}:10: value 4 of the row, 'x7', is not a number" in err, err


def test_an_ascii_grid_in_degrees_without_a_prj_is_refused_with_the_fix(tmp_path, capsys):
    asc = tmp_path / "srtm.asc"
    heights = plane(41, 61, 1, 1)
    asc.write_text("ncols 61\nnrows 41\nxllcorner -84.3\nyllcorner 36.55\n"
                   "cellsize 0.000833333\nNODATA_value -9999\n"
                   + "\n".join(" ".join(f"{v:g}" for v in row) for row in heights) + "\n")
    code, _, err = validate(tmp_path, capsys, asc)
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "cellsize 0.000833333 at corner (-84.3, 36.55) looks like degrees, but a grid " \
        "without a .prj is read in metres: add srtm.prj" in err
    asc.with_suffix(".prj").write_text(CRS.from_epsg(4326).to_wkt())
    code, out, err = validate(tmp_path, capsys, asc, 5.0)
    assert code == 0, err
    assert "(degrees); reprojected to a transverse Mercator" in line(out, "note: ")
