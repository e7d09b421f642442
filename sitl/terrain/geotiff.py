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

from sitl.terrain.model_area import Area, WindowError, covering, nodata_values, place
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


def read_geotiff(path: Path, window=None, nodata: float | None = None) -> Area:
    """The model's cells covering ``window`` (sitl.terrain.settings.WindowSettings; all of
    them without one), read from the file in the window only: heights (ny, nx) float64 in
    metres, row i along +y (south to north), NaN where unknown (the file's nodata, and
    ``nodata`` in the file's own height unit for a model that does not tag it); the (east,
    north) cell size in metres; notes for the user (what was assumed or converted); with a
    CRS, the model's georeference. Raises ValueError with the reason on a file that cannot
    be a model, WindowError on a window off it."""
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
            return _read(src, path, window, nodata)
    except ProjError as exc:  # a CRS or transformation PROJ cannot work with
        raise ValueError(f"its CRS: {' '.join(str(exc).split())[:160]}") from None
    except RasterioError as exc:
        cause = exc.__cause__ or exc.__context__
        why = " ".join(str(cause or exc).split())
        if "not recognized" in why:
            raise ValueError(f"not a {what} (nor any raster format GDAL reads)") from None
        raise ValueError(f"damaged or truncated {what} ({why[:160]})") from None


def _read(src, path: Path, window, nodata: float | None) -> Area:
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
    if window is None and src.width * src.height > MAX_CELLS:  # before reading: gigabytes
        raise ValueError(
            f"{src.height} x {src.width} cells, more than the {MAX_CELLS:,} a world may hold "
            "(memory): fly a window of it (world.window), or crop or coarsen it "
            "(gdal_translate -srcwin, gdalwarp -tr)"
        )
    notes: list[str] = []
    scale, offset = _scale_offset(src, band)
    if (scale, offset) != (1.0, 0.0):
        notes.append(f"{path}: heights are the stored values x {scale:g} + {offset:g} (the "
                     "band's scale and offset)")
    if src.crs is None:
        z_unit = _height_unit(src, None, None, path, notes)
        said = _band_unit(src) is not None  # heights in the band's own unit
        notes.append(f"{path}: no CRS; cells taken as metres" + ("" if said else ", heights too"))
        cells = (abs(t.a), abs(t.e))
        return _read_grid(src, band, window, cells, z_unit, notes, None, nodata)
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
        cells = (abs(t.a) * unit, abs(t.e) * unit)
        return _read_grid(src, band, window, cells, z_unit, notes, None, nodata)
    lon, lat = _centre_lonlat(src, horizontal)
    scale = 0.0 if horizontal.is_geographic else _scale_error(horizontal, lon, lat)
    if horizontal.is_geographic or scale > SCALE_TOLERANCE:
        grid = _LocalGrid(src, horizontal, lon, lat)
        what = ("geographic (degrees)" if horizontal.is_geographic
                else f"scale off by {scale:.0%} at the model")
        notes.append(
            f"{path}: {_label(horizontal)} is {what}; reprojected to a transverse Mercator "
            f"centred at {lat:.5f}, {lon:.5f} ({grid.cell[0]:.3g} x {grid.cell[1]:.3g} m cells)"
        )
        if window is None:
            heights = _heights(src, band, nodata)
            out = grid.reproject(heights, t, grid.transform, (grid.height, grid.width))
            return Area(_south_up(out, grid.transform) * z_unit, grid.cell, tuple(notes),
                        (grid.width, grid.height), (0.0, 0.0), None,
                        georef=grid.georef())
        return grid.read_window(src, band, window, z_unit, notes, nodata)
    from lsd.georef import from_crs

    xy_unit = from_crs(horizontal, path).horizontal_unit
    cells = (abs(t.a) * xy_unit, abs(t.e) * xy_unit)
    return _read_grid(src, band, window, cells, z_unit, notes, horizontal, nodata)


def _read_grid(src, band: int, window, cells: tuple[float, float], z_unit: float,
               notes: list[str], horizontal, nodata: float | None) -> Area:
    """A model taken on the file's own grid: its cells in ``window`` (all without one)."""
    t = src.transform
    model_cells = (src.width, src.height)
    georef = None if horizontal is None else _Georef(horizontal, t, model_cells, cells)
    if window is None:
        heights = _heights(src, band, nodata)
        return Area(_south_up(heights, t) * z_unit, cells, tuple(notes), model_cells,
                    (0.0, 0.0), None, georef=georef)
    centre_xy, centre = None, ""
    if _in_degrees(window):
        if horizontal is None:
            raise WindowError(
                "window.center: {lat, lon} needs a model with a geographic or projected "
                f"CRS; {src.name} has none: give [x, y] metres from its south-west corner"
            )
        centre = _degrees(window)
        centre_xy = georef.to_model(window.center.lon, window.center.lat, "window.center")
    box = place(window, model_cells, cells, centre_xy, centre)
    i0, i1, j0, j1 = covering(box, cells, model_cells)
    from rasterio.windows import Window

    col = j0 if t.a > 0 else model_cells[0] - 1 - j1
    row = model_cells[1] - 1 - i1 if t.e < 0 else i0
    _fits(j1 - j0 + 1, i1 - i0 + 1, "the model's")
    heights = _heights(src, band, nodata, Window(col, row, j1 - j0 + 1, i1 - i0 + 1))
    return Area(_south_up(heights, t) * z_unit, cells, tuple(notes), model_cells,
                (j0 * cells[0], i0 * cells[1]), box, centre, georef)


def _heights(src, band: int, nodata: float | None, window=None) -> np.ndarray:
    """Band ``band`` (of ``window``) as float64 heights in the band's unit: the stored values
    times the band's scale plus its offset (GDAL's unscaled values: DEMs stored as integers
    of centimetres or decimetres say so there), NaN where the file masks it (its nodata, an
    alpha band) or where it stores ``nodata``, a value the file does not tag (compared with
    the stored values, as a nodata tag is)."""
    heights = src.read(band, masked=True, window=window).astype(np.float64).filled(np.nan)
    if nodata is not None:
        heights[np.isin(heights, nodata_values((nodata,)))] = np.nan
    scale, offset = _scale_offset(src, band)
    if (scale, offset) != (1.0, 0.0):
        heights = heights * scale + offset
    return heights


def _scale_offset(src, band: int) -> tuple[float, float]:
    """The band's (scale, offset); ValueError on one that cannot give heights."""
    scale, offset = float(src.scales[band - 1]), float(src.offsets[band - 1])
    if not (np.isfinite(scale) and scale != 0 and np.isfinite(offset)):
        raise ValueError(f"band {band} has scale {scale:g} and offset {offset:g}: heights are "
                         "stored value x scale + offset, so the scale must be a non-zero "
                         "number (gdal_edit.py -scale 1 -offset 0 if the values are heights)")
    return scale, offset


def _fits(nx: int, ny: int, whose: str) -> None:
    """Refuses reading more than MAX_CELLS cells of a window."""
    if nx * ny > MAX_CELLS:
        raise WindowError(
            f"window.size: {nx} x {ny} of {whose} cells, more than the {MAX_CELLS:,} a world "
            "may hold (memory): a smaller window, or coarsen the model (gdalwarp -tr)"
        )


def _in_degrees(window) -> bool:
    return window.center is not None and not isinstance(window.center, tuple)


def _degrees(window) -> str:
    return f"lat {window.center.lat:.6g}, lon {window.center.lon:.6g}"


class _Georef:
    """Where a model's grid lies on the Earth: model metres (from the centre of its
    south-west cell) to and from WGS84 degrees, through the CRS of the grid with transform
    ``t`` (the file's own, or the transverse Mercator a model in degrees is reprojected to)."""

    def __init__(self, crs, t, model_cells: tuple[int, int], cells: tuple[float, float]
                 ) -> None:
        self.crs, self.t, self.model_cells, self.cells = crs, t, model_cells, cells

    def to_model(self, lon: float, lat: float, field: str) -> tuple[float, float]:
        """Model metres of a WGS84 longitude and latitude. Raises WindowError naming
        ``field`` when the point has no place in the CRS."""
        from pyproj import Transformer

        x, y = Transformer.from_crs("EPSG:4326", self.crs, always_xy=True).transform(lon, lat)
        if not (np.isfinite(x) and np.isfinite(y)):
            raise WindowError(f"{field}: {lat:g}, {lon:g} has no place in {self.crs.name}")
        col, row = ~self.t @ (x, y)
        t, (nx, ny) = self.t, self.model_cells
        j = col - 0.5 if t.a > 0 else nx - 0.5 - col
        i = ny - 0.5 - row if t.e < 0 else row - 0.5
        return j * self.cells[0], i * self.cells[1]

    def to_wgs84(self, x: float, y: float) -> tuple[float, float]:
        """WGS84 (longitude, latitude) of the point ``x``, ``y`` model metres."""
        from pyproj import Transformer

        t, (nx, ny) = self.t, self.model_cells
        j, i = x / self.cells[0], y / self.cells[1]
        col = j + 0.5 if t.a > 0 else nx - 0.5 - j
        row = ny - 0.5 - i if t.e < 0 else i + 0.5
        lon, lat = Transformer.from_crs(self.crs, "EPSG:4326", always_xy=True).transform(
            *_at(t, col, row))
        return float(lon), float(lat)


class _LocalGrid:
    """The grid in metres of a model in degrees (or a CRS whose scale is off at it): a
    transverse Mercator centred at (lon, lat) on the CRS's own datum, with the metre size of
    the file's centre cell; the whole model's extent is known without reading it."""

    def __init__(self, src, horizontal, lon: float, lat: float) -> None:
        from pyproj import Transformer
        from pyproj.crs import ProjectedCRS
        from pyproj.crs.coordinate_operation import TransverseMercatorConversion
        from rasterio.crs import CRS as RasterioCRS
        from rasterio.warp import calculate_default_transform

        self.local = ProjectedCRS(TransverseMercatorConversion(lat, lon),
                                  geodetic_crs=horizontal.geodetic_crs)
        t = src.transform
        col, row = src.width / 2, src.height / 2
        corners = [_at(t, col, row), _at(t, col + 1, row), _at(t, col, row + 1)]
        to_local = Transformer.from_crs(horizontal, self.local, always_xy=True)
        (x0, y0), (x1, y1), (x2, y2) = (to_local.transform(*c) for c in corners)
        self.cell = (float(np.hypot(x1 - x0, y1 - y0)), float(np.hypot(x2 - x0, y2 - y0)))
        self.src_crs = RasterioCRS.from_wkt(horizontal.to_wkt())
        self.dst_crs = RasterioCRS.from_wkt(self.local.to_wkt())
        self.transform, self.width, self.height = calculate_default_transform(
            self.src_crs, self.dst_crs, src.width, src.height, *src.bounds,
            resolution=self.cell
        )
        self.cell = (abs(self.transform.a), abs(self.transform.e))

    def reproject(self, heights: np.ndarray, src_t, dst_t, shape: tuple[int, int]
                  ) -> np.ndarray:
        """Heights (bilinear, nodata kept) on the local grid ``dst_t`` of ``shape``."""
        from rasterio.warp import Resampling, reproject

        out = np.full(shape, np.nan)
        reproject(heights, out, src_transform=src_t, src_crs=self.src_crs, src_nodata=np.nan,
                  dst_transform=dst_t, dst_crs=self.dst_crs, dst_nodata=np.nan,
                  resampling=Resampling.bilinear)
        return out

    def georef(self) -> _Georef:
        return _Georef(self.local, self.transform, (self.width, self.height), self.cell)

    def read_window(self, src, band: int, window, z_unit: float, notes: list[str],
                    nodata: float | None) -> Area:
        """The local grid's cells covering ``window``, from the file's cells under them
        (with a margin for the bilinear resampling) only."""
        from rasterio import windows
        from rasterio.warp import transform_bounds

        model_cells = (self.width, self.height)
        centre_xy, centre = None, ""
        if _in_degrees(window):
            centre = _degrees(window)
            centre_xy = self.georef().to_model(window.center.lon, window.center.lat,
                                               "window.center")
        box = place(window, model_cells, self.cell, centre_xy, centre)
        i0, i1, j0, j1 = covering(box, self.cell, model_cells)
        _fits(j1 - j0 + 1, i1 - i0 + 1, "the model's")
        out_window = windows.Window(j0, self.height - 1 - i1, j1 - j0 + 1, i1 - i0 + 1)
        out_t = windows.transform(out_window, self.transform)
        bounds = transform_bounds(self.dst_crs, self.src_crs,
                                  *windows.bounds(out_window, self.transform), densify_pts=21)
        margin = 2  # source cells: bilinear needs the neighbours of the edge cells
        read = windows.from_bounds(*bounds, transform=src.transform)
        col0 = int(np.floor(read.col_off)) - margin
        row0 = int(np.floor(read.row_off)) - margin
        col1 = int(np.ceil(read.col_off + read.width)) + margin
        row1 = int(np.ceil(read.row_off + read.height)) + margin
        read = windows.Window(col0, row0, col1 - col0, row1 - row0).intersection(
            windows.Window(0, 0, src.width, src.height))
        _fits(int(read.width), int(read.height), "the file's")
        heights = _heights(src, band, nodata, read)
        out = self.reproject(heights, src.window_transform(read), out_t,
                             (int(out_window.height), int(out_window.width)))
        return Area(_south_up(out, out_t) * z_unit, self.cell, tuple(notes), model_cells,
                    (j0 * self.cell[0], i0 * self.cell[1]), box, centre, self.georef())


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


def _at(t, col: float, row: float) -> tuple[float, float]:
    """CRS coordinates of the point (col, row) in pixel units (corner (0, 0)). Written out:
    affine 3 deprecates ``t * (col, row)`` and older affine releases lack ``t @ (col, row)``."""
    return t.c + t.a * col + t.b * row, t.f + t.d * col + t.e * row


def _label(crs) -> str:
    code = crs.to_epsg(min_confidence=70)
    return f"EPSG:{code}" if code else repr(crs.name)
