"""GeoTIFF elevation models, read with rasterio and pyproj (the optional ``geotiff`` extra).

Real DEMs come as GeoTIFF in a projected CRS in metres (UTM, national grids), in feet (US
state planes, international or US survey feet) or in geographic degrees (SRTM, Copernicus
GLO-30). The simulation works on a level grid in metres, so:

- **projected CRS**: cell sizes go from the CRS's unit to metres, and heights from the unit
  of the vertical CRS, else of the band (GDAL's unit type), else of x and y, as LAS files
  have it (:func:`lsd.georef.from_crs`, in one line when assumed);
- **a CRS whose scale at the model is off by more than 1 %** (geographic degrees, Web
  Mercator): reprojected (bilinear) to a transverse Mercator centred on the model on the
  file's own datum, at the metre size of a cell there; heights in metres unless the file
  gives their unit;
- **no CRS** but a geotransform: cells and heights taken as metres, in one line.

The same reader takes the other formats DEMs are distributed in that GDAL reads
(:data:`GDAL_SUFFIXES`: SRTM ``.hgt``, DTED, ERDAS ``.img``, ``.bil``/``.flt`` with their
``.hdr``, GDAL's ``.vrt`` mosaics).

Refused, each with one reason: no geotransform (a plain TIFF, ground control points only),
a rotated or sheared one, an image or more than one band of heights (bands beyond the first
that are alpha are read as its mask), a file rasterio cannot read or a damaged one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sitl.terrain.settings import MAX_CELLS

GEOTIFF_SUFFIXES = (".tif", ".tiff")
GDAL_SUFFIXES = (*GEOTIFF_SUFFIXES, ".hgt", ".dt0", ".dt1", ".dt2", ".img", ".bil", ".flt",
                 ".vrt")
"""Elevation-model files read through rasterio (GDAL): GeoTIFF, and the other forms DEMs
come in (SRTM tiles as .hgt, DTED levels 0-2, ERDAS Imagine, ESRI BIL/FLT, VRT mosaics)."""

SCALE_TOLERANCE = 0.01
"""Largest scale error of a projected CRS at the model that is taken as metres (UTM has
at most 0.1 %, a state plane 0.01 %; Web Mercator 41 % at 45 deg latitude)."""

_IMAGE_BANDS = frozenset({"red", "green", "blue", "palette", "hue", "cyan", "Y"})
# Unit names GDAL writes as a band's unit type, beyond the EPSG and PROJ names pyproj knows.
_UNIT_ALIASES = {"meter": "metre", "meters": "metre", "metres": "metre", "feet": "foot",
                 "ftus": "us survey foot", "us_survey_foot": "us survey foot",
                 "us survey feet": "us survey foot"}


def read_geotiff(path: Path) -> tuple[np.ndarray, tuple[float, float], list[str]]:
    """Heights (ny, nx) float64 in metres, row i along +y (south to north), NaN where
    unknown; the (east, north) cell size in metres; notes for the user (what was assumed or
    converted). Raises ValueError with the reason on a file that cannot be a model."""
    try:
        import pyproj  # noqa: F401 - the CRS and its units
        import rasterio
        from rasterio.errors import RasterioError
    except ImportError as exc:  # optional extra
        raise ValueError(
            f"{path.suffix} elevation models need rasterio and pyproj: "
            "pip install 'landing-autonomy[geotiff]'"
        ) from exc
    from pyproj.exceptions import ProjError

    what = "GeoTIFF" if path.suffix.lower() in GEOTIFF_SUFFIXES else f"{path.suffix} raster"
    try:
        with rasterio.open(path) as src:
            return _read(src, path)
    except ProjError as exc:  # a CRS or transformation PROJ cannot work with
        raise ValueError(f"its CRS: {' '.join(str(exc).split())[:160]}") from None
    except RasterioError as exc:
        cause = exc.__cause__ or exc.__context__
        why = " ".join(str(cause or exc).split())
        if "not recognized" in why:
            raise ValueError(f"not a {what} (nor any raster format GDAL reads)") from None
        raise ValueError(f"damaged or truncated {what} ({why[:160]})") from None


def _read(src, path: Path) -> tuple[np.ndarray, tuple[float, float], list[str]]:
    band = _height_band(src)
    t = src.transform
    if t.is_identity:
        how = "ground control points only" if src.gcps[0] else "no geotransform"
        raise ValueError(
            f"not georeferenced ({how}): give it a CRS and cell size (gdalwarp or "
            "gdal_translate -a_srs -a_ullr), or save the grid as .npy with source_cell_size"
        )
    if not t.is_rectilinear:
        raise ValueError(
            f"rotated or sheared geotransform {tuple(round(v, 6) for v in t[:6])}: warp it "
            "north-up first (gdalwarp -t_srs with the file's own CRS)"
        )
    if src.width * src.height > MAX_CELLS:  # before reading: a national tile is gigabytes
        raise ValueError(
            f"{src.height} x {src.width} cells, more than the {MAX_CELLS:,} a world may hold "
            "(memory): crop or coarsen it (gdal_translate -srcwin, gdalwarp -tr)"
        )
    heights = src.read(band, masked=True).astype(np.float64).filled(np.nan)
    notes: list[str] = []
    if src.crs is None:
        z_unit = _height_unit(src, None, None, path, notes)
        said = _band_unit(src) is not None  # heights in the band's own unit
        notes.append(f"{path}: no CRS; cells taken as metres" + ("" if said else ", heights too"))
        return _south_up(heights, t) * z_unit, (abs(t.a), abs(t.e)), notes
    from pyproj import CRS

    crs = CRS.from_wkt(src.crs.to_wkt())
    horizontal = crs.sub_crs_list[0] if crs.is_compound else crs
    if horizontal.is_geocentric:
        raise ValueError(f"CRS {horizontal.name!r} is geocentric, not a map of heights")
    z_unit = _height_unit(src, crs, horizontal, path, notes)
    if not (horizontal.is_geographic or horizontal.is_projected):
        # A local (engineering) grid, as some LiDAR software writes: level, in its unit.
        axis = horizontal.axis_info[0]
        if axis.unit_name == "unknown" or not axis.unit_conversion_factor:
            raise ValueError(f"CRS {horizontal.name!r} is neither projected nor geographic")
        unit = float(axis.unit_conversion_factor)
        notes.append(f"{path}: local CRS {horizontal.name!r}; taken as a level grid in its "
                     f"unit ({axis.unit_name})")
        return _south_up(heights, t) * z_unit, (abs(t.a) * unit, abs(t.e) * unit), notes
    lon, lat = _centre_lonlat(src, horizontal)
    scale = 0.0 if horizontal.is_geographic else _scale_error(horizontal, lon, lat)
    if horizontal.is_geographic or scale > SCALE_TOLERANCE:
        heights, t = _to_local_metres(heights, src, horizontal, lon, lat)
        what = ("geographic (degrees)" if horizontal.is_geographic
                else f"scale off by {scale:.0%} at the model")
        notes.append(
            f"{path}: {_label(horizontal)} is {what}; reprojected to a transverse Mercator "
            f"centred at {lat:.5f}, {lon:.5f} ({abs(t.a):.3g} x {abs(t.e):.3g} m cells)"
        )
        return _south_up(heights, t) * z_unit, (abs(t.a), abs(t.e)), notes
    from lsd.georef import from_crs

    xy_unit = from_crs(horizontal, path).horizontal_unit
    cells = (abs(t.a) * xy_unit, abs(t.e) * xy_unit)
    return _south_up(heights, t) * z_unit, cells, notes


def _height_band(src) -> int:
    """The band of heights (1); refuses an image and a file with several bands of values."""
    interp = [c.name for c in src.colorinterp]
    if interp[0] in _IMAGE_BANDS:
        raise ValueError(f"an image ({', '.join(interp)} bands), not an elevation model")
    if all(c == "alpha" for c in interp[1:]):
        return 1  # heights, with an alpha band read as their mask
    raise ValueError(
        f"{src.count} bands ({', '.join(interp)}): an elevation model has one band of "
        "heights; write that band alone (gdal_translate -b N)"
    )


def _south_up(heights: np.ndarray, t) -> np.ndarray:
    """Rows south to north and columns west to east, whichever way the file stores them."""
    if t.e < 0:  # north-up, the usual way
        heights = heights[::-1]
    if t.a < 0:
        heights = heights[:, ::-1]
    return np.ascontiguousarray(heights)


def _height_unit(src, crs, horizontal, path: Path, notes: list[str]) -> float:
    """Metres per height unit: the vertical CRS's unit, else the band's unit type, else the
    unit of x and y of a projected CRS (as LAS has it; said in a note) or metres."""
    if crs is not None and crs.is_compound and len(crs.sub_crs_list) > 1:
        return float(crs.sub_crs_list[1].axis_info[0].unit_conversion_factor)
    factor = _band_unit(src)
    if factor is not None:
        return factor
    if named := (src.units[0] or "").strip():
        notes.append(f"{path}: band unit {named!r} is not a unit of length pyproj knows; "
                     "ignored")
    if horizontal is None:
        return 1.0
    if not horizontal.is_geographic and not horizontal.is_projected:
        return float(horizontal.axis_info[0].unit_conversion_factor or 1.0)
    if horizontal.is_projected:
        from lsd.georef import from_crs

        georef = from_crs(horizontal, path)
        if georef.note:
            notes.append(georef.note.replace("z taken", "heights taken"))
        return georef.vertical_unit
    return 1.0


def _band_unit(src) -> float | None:
    """Metres per unit of band 1's unit type as GDAL gives it ("m", "metre", "ft",
    "US survey foot"), or None when it has none or pyproj knows no unit of length by
    that name."""
    from pyproj.database import get_units_map

    key = (src.units[0] or "").strip().lower()
    if not key:
        return None
    key = _UNIT_ALIASES.get(key, key)
    for unit in get_units_map(category="linear").values():
        if key in (unit.name.lower(), (unit.proj_short_name or "").lower()):
            return float(unit.conv_factor)
    return None


def _centre_lonlat(src, horizontal) -> tuple[float, float]:
    """Longitude, latitude (degrees on the CRS's own datum) of the model's centre."""
    from pyproj import Transformer

    x, y = _at(src.transform, src.width / 2, src.height / 2)
    to_lonlat = Transformer.from_crs(horizontal, horizontal.geodetic_crs, always_xy=True)
    lon, lat = to_lonlat.transform(x, y)
    if not (np.isfinite(lon) and np.isfinite(lat) and abs(lat) <= 90):
        raise ValueError(f"its centre ({x:g}, {y:g}) is not on the globe of {horizontal.name}")
    return float(lon), float(lat)


def _scale_error(horizontal, lon: float, lat: float) -> float:
    """How far a projected CRS's scale is from 1 at (lon, lat), along either axis."""
    from pyproj import Proj

    try:
        f = Proj(horizontal).get_factors(lon, lat)
        return max(abs(f.meridional_scale - 1.0), abs(f.parallel_scale - 1.0))
    except Exception:  # noqa: BLE001 - a projection PROJ cannot give factors for: keep it
        return 0.0


def _to_local_metres(heights: np.ndarray, src, horizontal, lon: float, lat: float):
    """Heights reprojected (bilinear, nodata kept) to a transverse Mercator centred at
    (lon, lat) on the CRS's own datum, with the metre size of the file's centre cell;
    returns them (north-up) with their transform."""
    from pyproj import Transformer
    from pyproj.crs import ProjectedCRS
    from pyproj.crs.coordinate_operation import TransverseMercatorConversion
    from rasterio.crs import CRS as RasterioCRS
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    local = ProjectedCRS(TransverseMercatorConversion(lat, lon),
                         geodetic_crs=horizontal.geodetic_crs)
    t = src.transform
    col, row = src.width / 2, src.height / 2
    corners = [_at(t, col, row), _at(t, col + 1, row), _at(t, col, row + 1)]
    to_local = Transformer.from_crs(horizontal, local, always_xy=True)
    (x0, y0), (x1, y1), (x2, y2) = (to_local.transform(*c) for c in corners)
    cell = (float(np.hypot(x1 - x0, y1 - y0)), float(np.hypot(x2 - x0, y2 - y0)))
    src_crs = RasterioCRS.from_wkt(horizontal.to_wkt())
    dst_crs = RasterioCRS.from_wkt(local.to_wkt())
    dst_t, width, height = calculate_default_transform(
        src_crs, dst_crs, src.width, src.height, *src.bounds, resolution=cell
    )
    out = np.full((height, width), np.nan)
    reproject(heights, out, src_transform=t, src_crs=src_crs, src_nodata=np.nan,
              dst_transform=dst_t, dst_crs=dst_crs, dst_nodata=np.nan,
              resampling=Resampling.bilinear)
    return out, dst_t


def _at(t, col: float, row: float) -> tuple[float, float]:
    """CRS coordinates of the point (col, row) in pixel units (corner (0, 0))."""
    return t.c + t.a * col + t.b * row, t.f + t.d * col + t.e * row


def _label(crs) -> str:
    code = crs.to_epsg(min_confidence=70)
    return f"EPSG:{code}" if code else repr(crs.name)
