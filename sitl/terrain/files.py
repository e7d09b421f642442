"""The ``file`` world: a real elevation model read from disk and resampled to the
simulation grid.

Formats: ``.npy`` (row i along +y, south to north; the cell size comes from the settings),
ESRI ASCII grid ``.asc`` (north-up rows, header with ``cellsize`` and ``NODATA_value``), and
GeoTIFF through rasterio (optional extra ``geotiff``; imported only when needed). Missing
values (NODATA, NaN) take the nearest valid height.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy import ndimage

from sitl.terrain.settings import FileTerrainSettings

_ASC_KEYS = (
    "ncols",
    "nrows",
    "xllcorner",
    "yllcorner",
    "xllcenter",
    "yllcenter",
    "cellsize",
    "nodata_value",
)


def generate(
    settings: FileTerrainSettings, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float]]:
    """(grid, origin) of the elevation model, resampled to ``settings.cell_size`` and
    placed so that home (0, 0) is at ``settings.home`` (default: the model's centre)."""
    heights, source_cell = read_elevation(settings.path, settings.source_cell_size)
    heights = heights * settings.vertical_scale
    src_ny, src_nx = heights.shape
    width, depth = (src_nx - 1) * source_cell, (src_ny - 1) * source_cell
    cs = settings.cell_size
    nx = int(np.floor(width / cs + 1e-9)) + 1
    ny = int(np.floor(depth / cs + 1e-9)) + 1
    if nx < 2 or ny < 2:
        raise ValueError(
            f"path: {settings.path} spans {width:g} x {depth:g} m, less than two {cs:g} m cells"
        )
    # Bilinear resampling at the simulation cell centres (source index units).
    rows = np.arange(ny) * (cs / source_cell)
    cols = np.arange(nx) * (cs / source_cell)
    grid = ndimage.map_coordinates(
        heights, np.meshgrid(rows, cols, indexing="ij"), order=1, mode="nearest"
    ).astype(np.float32)
    hx, hy = settings.home if settings.home is not None else (width / 2, depth / 2)
    if not (0 <= hx <= width and 0 <= hy <= depth):
        raise ValueError(f"home: {settings.home} is outside the model's {width:g} x {depth:g} m")
    return grid, (-hx, -hy)


def read_elevation(path: Path, source_cell_size: float | None = None) -> tuple[np.ndarray, float]:
    """Heights (ny, nx) float64 with row i along +y (south to north), and the cell size
    in metres. Raises ValueError("path: ...") on an unreadable or malformed file."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            heights = np.load(path, allow_pickle=False).astype(np.float64)
            cell = source_cell_size
            nodata = None
        elif suffix == ".asc":
            heights, cell, nodata = _read_asc(path)
        elif suffix in (".tif", ".tiff"):
            heights, cell, nodata = _read_geotiff(path)
        else:
            raise ValueError(f"unsupported format {suffix!r}")
    except (OSError, ValueError, TypeError) as exc:
        raise ValueError(f"path: cannot read {path}: {exc}") from exc
    if cell is None or not np.isfinite(cell) or cell <= 0:
        raise ValueError(f"path: {path}: no positive cell size")
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise ValueError(f"path: {path}: need a 2-D grid of at least 2 x 2, got {heights.shape}")
    return _fill_missing(heights, nodata, path), float(cell)


def _fill_missing(heights: np.ndarray, nodata: float | None, path: Path) -> np.ndarray:
    missing = ~np.isfinite(heights)
    if nodata is not None:
        missing |= heights == nodata
    if missing.all():
        raise ValueError(f"path: {path}: no valid heights")
    if missing.any():
        # nearest valid cell, via the Euclidean distance transform's indices
        idx = ndimage.distance_transform_edt(missing, return_distances=False, return_indices=True)
        heights = heights[tuple(idx)]
    return heights


def _read_asc(path: Path) -> tuple[np.ndarray, float, float | None]:
    header: dict[str, float] = {}
    with path.open() as f:
        while True:
            pos = f.tell()
            line = f.readline()
            parts = line.split()
            if len(parts) == 2 and parts[0].lower() in _ASC_KEYS:
                header[parts[0].lower()] = float(parts[1])
            else:
                f.seek(pos)
                break
        values = np.loadtxt(f, dtype=np.float64, ndmin=2)
    for key in ("ncols", "nrows", "cellsize"):
        if key not in header:
            raise ValueError(f"ESRI ASCII header lacks {key}")
    shape = (int(header["nrows"]), int(header["ncols"]))
    if values.size != shape[0] * shape[1]:
        raise ValueError(f"expected {shape[0]} x {shape[1]} values, found {values.size}")
    # ESRI rows run north to south; ours run south to north.
    return values.reshape(shape)[::-1], header["cellsize"], header.get("nodata_value")


def _read_geotiff(path: Path) -> tuple[np.ndarray, float, float | None]:
    try:
        import rasterio
    except ImportError as exc:  # optional extra
        raise ValueError("GeoTIFF needs rasterio: pip install 'landing-autonomy[geotiff]'") from exc
    with rasterio.open(path) as src:
        band = src.read(1).astype(np.float64)
        sx, sy = src.res
        if not np.isclose(sx, sy):
            raise ValueError(f"non-square cells {sx} x {sy} are not supported")
        if src.crs is not None and src.crs.is_geographic:
            raise ValueError("geographic (degree) coordinates: reproject to metres first")
        return band[::-1], float(sx), src.nodata
