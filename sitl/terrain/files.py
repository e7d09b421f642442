"""The ``file`` world: a real elevation model read from disk and resampled to the
simulation grid.

Formats: ``.npy`` (row i along +y, south to north; the cell size comes from the settings),
ESRI ASCII grid ``.asc`` (north-up rows, header with ``cellsize`` and ``NODATA_value``; with
a ``.prj`` beside it, read through GDAL as a georeferenced model, as a GeoTIFF is), and
GeoTIFF (:mod:`sitl.terrain.geotiff`: its CRS and units to metres; optional extra
``geotiff``, imported only when needed).

A world is the whole model or, with ``window``, an area of it (:mod:`sitl.terrain.model_area`):
a GDAL-read file is read in the window only, a .npy or .asc (limited to MAX_CELLS by
themselves) is cropped to it; home is then on the window.

The model is taken as it is: outside its grid there is no ground, and missing values (ESRI
``NODATA_value``, GeoTIFF nodata, NaN) stay unknown. The world's ``known`` mask carries
both to the sensors (no return there, so no site is detected there); its height grid holds
the nearest known height in unknown cells only so that rays march through a continuous
surface.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy import ndimage

from sitl.terrain.esri_ascii import looks_geographic, projection_file, read_asc
from sitl.terrain.file_errors import GridFileError
from sitl.terrain.geotiff import GDAL_SUFFIXES
from sitl.terrain.model_area import Area, WindowError, crop, nodata_values
from sitl.terrain.settings import MAX_CELLS, FileTerrainSettings, GeoPoint, WindowSettings


def _grid_shape(settings: FileTerrainSettings, area: Area) -> tuple[int, int, float, float]:
    """(nx, ny, width, depth) of the simulation grid of the model's ``area``. Raises
    ValueError when it is too small, too large or home is off it."""
    _, _, width, depth = area.box
    what = (f"{settings.path} spans" if area.window is None
            else f"the window of {settings.path} spans")
    cs = settings.cell_size
    nx = int(np.floor(width / cs + 1e-9)) + 1
    ny = int(np.floor(depth / cs + 1e-9)) + 1
    if nx < 2 or ny < 2:
        raise ValueError(
            f"path: {what} {width:g} x {depth:g} m, less than two {cs:g} m cells"
        )
    if nx * ny > MAX_CELLS:
        raise ValueError(
            f"cell_size: {what} {width:g} x {depth:g} m, {nx * ny:.3g} cells of "
            f"{cs:g} m, more than {MAX_CELLS}"
        )
    home = home_on_area(settings, area)
    if home is not None:
        hx, hy = home
        if not (-1e-6 <= hx <= width + 1e-6 and -1e-6 <= hy <= depth + 1e-6):
            where = "model's" if area.window is None else "window's"
            said = (f"{_degrees(settings.home)} (x {hx:.6g}, y {hy:.6g} m)"
                    if isinstance(settings.home, GeoPoint) else f"{settings.home}")
            raise ValueError(
                f"home: {said} is outside the {where} {width:g} x {depth:g} m"
            )
    return nx, ny, width, depth


def home_on_area(settings: FileTerrainSettings, area: Area) -> tuple[float, float] | None:
    """Home in metres from the south-west corner of ``area``'s box (the window's, or the
    model's), or None when the settings leave it at the centre. Raises ValueError for home
    in degrees on a model without a coordinate system."""
    home = settings.home
    if not isinstance(home, GeoPoint):
        return home
    if area.georef is None:
        raise ValueError(
            "home: {lat, lon} needs a model with a coordinate system (a GeoTIFF or another "
            f"GDAL format with a CRS); {settings.path} has none: give (x, y) metres from its "
            "south-west corner"
        )
    x, y = area.georef.to_model(home.lon, home.lat, "home")
    return x - area.box[0], y - area.box[1]


def georeference(settings: FileTerrainSettings) -> tuple[float, float, float] | None:
    """(lat, lon, ground height) of the world's home on a model with a coordinate system
    (WGS84 degrees, metres in the model's vertical datum), None on one without."""
    area = _read(settings)
    if area.georef is None:
        return None
    nx, ny, width, depth = _grid_shape(settings, area)
    home = home_on_area(settings, area)
    hx, hy = home if home is not None else (width / 2, depth / 2)
    x, y = area.box[0] + hx, area.box[1] + hy
    lon, lat = area.georef.to_wgs84(x, y)
    heights = area.heights
    known = np.isfinite(heights)
    i = min(max(round((y - area.origin[1]) / area.cell[1]), 0), heights.shape[0] - 1)
    j = min(max(round((x - area.origin[0]) / area.cell[0]), 0), heights.shape[1] - 1)
    ground = heights[i, j] if known[i, j] else np.nanmedian(heights)
    return lat, lon, float(ground)


def _degrees(point: GeoPoint) -> str:
    return f"lat {point.lat:.6g}, lon {point.lon:.6g}"


def _read(settings: FileTerrainSettings) -> Area:
    return read_elevation(settings.path, settings.source_cell_size, settings.window,
                          settings.nodata)


def check_elevation(settings: FileTerrainSettings) -> None:
    """Read the model (kept for :func:`generate`) and check that it makes a world.

    Raises:
        ValueError: ``path: ...``, ``cell_size: ...``, ``window...: ...`` or ``home: ...``:
            unreadable or malformed, a window off it, more than MAX_CELLS cells once
            resampled, or home outside it.
    """
    _grid_shape(settings, _read(settings))


def describe_elevation(settings: FileTerrainSettings) -> list[str]:
    """What the model is in metres (``elevation model: ...``), the window flown
    (``window: ...``), then how it was read (``note: ...``: units assumed, a reprojection):
    lines for the user to check the file's units were taken right."""
    area = _read(settings)
    heights, (cx, cy) = area.heights, area.cell
    nx, ny = area.model_cells
    width, depth = area.model_size
    _grid_shape(settings, area)
    low, high = np.nanmin(heights), np.nanmax(heights)
    unknown = np.isnan(heights).mean()
    relief = (f"heights {low:.2f} .. {high:.2f} m"
              + (f", {unknown:.1%} unknown" if unknown else ""))
    model = (f"elevation model: {settings.path}: {nx} x {ny} cells of {cx:.4g} x {cy:.4g} m "
             f"({width:.6g} x {depth:.6g} m)")
    home = _describe_home(settings, area)
    if area.window is None:
        return [f"{model}, {relief}", *(f"note: {n}" for n in area.notes), *home]
    x0, y0, w, d = area.window
    at = f"{area.centre} " if area.centre else ""
    window = (f"window: {w:.6g} x {d:.6g} m centred at {at}(x {x0 + w / 2:.6g}, "
              f"y {y0 + d / 2:.6g} m from the model's south-west corner), "
              f"{heights.shape[1]} x {heights.shape[0]} cells read, {relief}")
    return [model, window, *(f"note: {n}" for n in area.notes), *home]


def _describe_home(settings: FileTerrainSettings, area: Area) -> list[str]:
    """``home: lat, lon, ground`` on a model with a coordinate system: where it is flown."""
    at = georeference(settings)
    if at is None:
        return []
    lat, lon, ground = at
    _, _, width, depth = _grid_shape(settings, area)
    hx, hy = home_on_area(settings, area) or (width / 2, depth / 2)
    whose = "model's" if area.window is None else "window's"
    return [f"home: lat {lat:.7f}, lon {lon:.7f} (x {hx:.6g}, y {hy:.6g} m from the {whose} "
            f"south-west corner), ground {ground:.2f} m"]


def model_extent(settings: FileTerrainSettings) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) ENU metres about home of the model's grid (of its window):
    where it has ground at all."""
    area = _read(settings)
    _, _, width, depth = _grid_shape(settings, area)
    home = home_on_area(settings, area)
    hx, hy = home if home is not None else (width / 2, depth / 2)
    return (-hx, width - hx, -hy, depth - hy)


def check_route(
    settings: FileTerrainSettings,
    waypoints: list[tuple[float, float, float]],
    search_rectangle: tuple[float, float],
    pattern_center_radius: float,
) -> None:
    """Refuse a route that leaves the model, where there is no ground to see or land on:
    a waypoint off it, a search pattern (``search_rectangle`` centred where the landing
    phase may start: any waypoint, a failsafe can start it on the way) reaching off it, or
    new pattern centres (within ``pattern_center_radius`` of the last waypoint) whose
    patterns may. Raises ValueError naming the setting and the coordinates."""
    xmin, xmax, ymin, ymax = model_extent(settings)
    model = (f"off the elevation model (x {xmin:g} .. {xmax:g}, y {ymin:g} .. {ymax:g} m "
             "about home)")

    def off(x: float, y: float, hx: float = 0.0, hy: float = 0.0) -> tuple[float, float] | None:
        """The corner of the box (x +- hx, y +- hy) farthest off the model, or None."""
        cx = x - hx if x - hx < xmin else x + hx if x + hx > xmax else None
        cy = y - hy if y - hy < ymin else y + hy if y + hy > ymax else None
        if cx is None and cy is None:
            return None
        return (x if cx is None else cx, y if cy is None else cy)

    for i, (x, y, _) in enumerate(waypoints):
        if off(x, y):
            raise ValueError(f"waypoints.{i}: ({x:g}, {y:g}) is {model}")
    w, h = search_rectangle
    for i, (x, y, _) in enumerate(waypoints):
        corner = off(x, y, w / 2, h / 2)
        if corner:
            raise ValueError(
                f"landing.search_rectangle: a {w:g} x {h:g} m search pattern around "
                f"waypoints.{i} ({x:g}, {y:g}) reaches ({corner[0]:g}, {corner[1]:g}), {model}"
            )
    x, y, _ = waypoints[-1]
    r = pattern_center_radius
    corner = off(x, y, w / 2 + r, h / 2 + r)
    if corner:
        raise ValueError(
            f"landing.pattern_center_radius: new {w:g} x {h:g} m search patterns centred "
            f"within {r:g} m of the last waypoint ({x:g}, {y:g}) may reach "
            f"({corner[0]:g}, {corner[1]:g}), {model}"
        )


def generate(
    settings: FileTerrainSettings, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float], np.ndarray]:
    """(grid, origin, known) of the elevation model (of its window), resampled to
    ``settings.cell_size`` and placed so that home (0, 0) is at ``settings.home`` (default:
    the centre). ``known`` is False in cells whose bilinear height needs an unknown source
    cell."""
    area = _read(settings)
    source_cell = area.cell
    known_source = np.isfinite(area.heights)
    heights = _nearest_known(area.heights, known_source) * settings.vertical_scale
    nx, ny, width, depth = _grid_shape(settings, area)
    cs = settings.cell_size
    # Bilinear resampling at the simulation cell centres (source index units), from the
    # window's south-west corner (the model's without a window: offset 0).
    x0, y0 = area.box[0] - area.origin[0], area.box[1] - area.origin[1]
    rows = y0 / source_cell[1] + np.arange(ny) * (cs / source_cell[1])
    cols = x0 / source_cell[0] + np.arange(nx) * (cs / source_cell[0])
    at = np.meshgrid(rows, cols, indexing="ij")
    grid = ndimage.map_coordinates(heights, at, order=1, mode="nearest").astype(np.float32)
    known = ndimage.map_coordinates(known_source.astype(np.float64), at, order=1, mode="nearest")
    home = home_on_area(settings, area)
    hx, hy = home if home is not None else (width / 2, depth / 2)
    return grid, (-hx, -hy), known >= 1.0 - 1e-6


def read_elevation(
    path: Path, source_cell_size: float | None = None, window: WindowSettings | None = None,
    nodata: float | None = None,
) -> Area:
    """The model's cells covering ``window`` (all of them without one): heights (ny, nx)
    float64 in metres with row i along +y (south to north), NaN where unknown (the file's
    nodata, and ``nodata``, a value in the file's own unit it does not tag); the
    (east, north) cell size in metres; notes for the user on how the file was read (units
    assumed, a reprojection); where they lie on the model. A GDAL-read file is read in the
    window only. Raises ValueError("path: ...") on an unreadable or malformed file, or one
    without a single known height, WindowError ("window...: ...") on a window off it.

    The last model read is kept (keyed by the file's path, size and modification time, and
    the window), so validating a mission and then flying it reads the file once.
    """
    path = Path(path)
    try:
        stat = path.stat()
    except OSError as exc:
        raise ValueError(f"path: cannot read {path}: {exc.strerror or exc}") from None
    key = (str(path.resolve()), stat.st_size, stat.st_mtime_ns, source_cell_size, window,
           nodata)
    if _LAST_READ and _LAST_READ[0] == key:
        return _LAST_READ[1]
    result = _read_elevation(path, source_cell_size, window, nodata)
    result.heights.setflags(write=False)
    _LAST_READ[:] = [key, result]
    return result


_LAST_READ: list = []


def _read_elevation(path: Path, source_cell_size: float | None, window,
                    nodata: float | None) -> Area:
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")  # a bad file is one line, not a library's warning
        return _read_elevation_quietly(path, source_cell_size, window, nodata)


def _read_elevation_quietly(path: Path, source_cell_size: float | None, window,
                            nodata: float | None) -> Area:
    suffix = path.suffix.lower()
    area = None
    try:
        if suffix == ".npy":
            heights = _load_npy(path)
            cells = (source_cell_size, source_cell_size)
            tagged = None
        elif suffix == ".asc":
            grid = read_asc(path)  # a malformed file is named by its line here, not by GDAL
            if projection_file(path) is not None:
                from sitl.terrain.geotiff import read_geotiff

                area = read_geotiff(path, window, nodata)  # GDAL takes the CRS from the .prj
            elif looks_geographic(grid):
                raise ValueError(
                    f"cellsize {grid.cell:g} at corner ({grid.corner[0]:g}, "
                    f"{grid.corner[1]:g}) looks like degrees, but a grid without a .prj is "
                    f"read in metres: add {path.with_suffix('.prj').name} (gdalsrsinfo -o "
                    "wkt1_esri EPSG:4326)"
                )
            else:
                heights = grid.heights[::-1]  # ESRI rows run north to south; ours south to north
                cells = (grid.cell, grid.cell)
                tagged = grid.nodata
        elif suffix in GDAL_SUFFIXES:
            from sitl.terrain.geotiff import read_geotiff

            area = read_geotiff(path, window, nodata)  # of the window only; nodata NaN
        else:
            raise ValueError(f"unsupported format {suffix!r}")
    except WindowError:  # names the setting itself
        raise
    except GridFileError as exc:  # names the file and the line itself
        raise ValueError(f"path: {exc}") from None
    except (OSError, ValueError, TypeError) as exc:
        raise ValueError(f"path: cannot read {path}: {exc}") from exc
    if area is not None:
        _check_grid(area.heights, area.cell, path)
        return replace(area, heights=_mark_missing(area.heights, (), path))
    _check_grid(heights, cells, path)
    cells = (float(cells[0]), float(cells[1]))
    marks = tuple(v for v in (tagged, nodata) if v is not None)
    return crop(_mark_missing(heights, marks, path), cells, (), window)


def _check_grid(heights: np.ndarray, cells, path: Path) -> None:
    if any(c is None or not np.isfinite(c) or c <= 0 for c in cells):
        raise ValueError(f"path: {path}: no positive cell size")
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise ValueError(f"path: {path}: need a 2-D grid of at least 2 x 2, got {heights.shape}")


def _mark_missing(heights: np.ndarray, nodata: tuple[float, ...], path: Path) -> np.ndarray:
    """Heights with NaN in the cells holding a value of ``nodata``."""
    missing = ~np.isfinite(heights)
    if nodata:
        missing |= np.isin(heights, nodata_values(nodata))
    if missing.all():
        raise ValueError(f"path: {path}: no valid heights (every cell is nodata)")
    return np.where(missing, np.nan, heights)


def _nearest_known(heights: np.ndarray, known: np.ndarray) -> np.ndarray:
    """Heights with each unknown cell given its nearest known cell's height."""
    if known.all():
        return heights
    idx = ndimage.distance_transform_edt(~known, return_distances=False, return_indices=True)
    return heights[tuple(idx)]


def _load_npy(path: Path) -> np.ndarray:
    """The heights of a .npy file whose header, read before the data, declares a 2-D array of
    numbers of at most MAX_CELLS cells (else GridFileError); ValueError if unreadable."""
    fmt = np.lib.format
    with path.open("rb") as f:
        try:
            version = fmt.read_magic(f)
        except ValueError:
            raise ValueError("not a NumPy .npy file") from None
        read_header = {(1, 0): fmt.read_array_header_1_0,
                       (2, 0): fmt.read_array_header_2_0}.get(version)
        if read_header is None:
            raise ValueError(f".npy format version {version[0]}.{version[1]}; versions 1.0 "
                             "and 2.0 hold a grid of numbers")
        try:
            shape, _, dtype = read_header(f)
        except Exception as exc:  # noqa: BLE001 - a damaged header raises several types
            raise ValueError(f"a damaged .npy header ({_one_line(exc)})") from None
        if any(n < 0 for n in shape):
            raise ValueError(f"a damaged .npy header (shape {shape})")
        if dtype.kind not in "fiub":
            raise GridFileError(f"{path}: holds {dtype} values, not numbers")
        if len(shape) != 2:
            raise GridFileError(f"{path}: holds a {len(shape)}-D array of shape {shape}; an "
                                "elevation model is a 2-D grid of heights")
        if math.prod(shape) > MAX_CELLS:
            raise GridFileError(f"{path}: {shape[0]} x {shape[1]} cells, more than the "
                                f"{MAX_CELLS:,} a world may hold (memory): crop or coarsen it")
        needed = f.tell() + math.prod(shape) * dtype.itemsize
        if path.stat().st_size < needed:
            raise ValueError(f"the file ends before the {shape[0]} x {shape[1]} values its "
                             f"header declares ({path.stat().st_size} of {needed} bytes)")
        f.seek(0)
        try:
            return fmt.read_array(f, allow_pickle=False).astype(np.float64)
        except Exception as exc:  # noqa: BLE001 - as for the header
            raise ValueError(_one_line(exc)) from None


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())[:200] or type(exc).__name__
