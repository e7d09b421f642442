"""The area of an elevation model a world is made of: the whole model, or the window of it
the mission asks for (``world.window``), so that a DEM as it is downloaded (a one-degree
SRTM or Copernicus tile, a 10 km LiDAR tile) can be flown without cropping it first.

Positions on a model are metres from its south-west corner: the centre of its south-west
cell on its grid in metres (the reprojected one for a model in degrees), as ``home`` is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

_EPS = 1e-6  # m: a window edge on the model's edge is on it


class WindowError(ValueError):
    """A window off its model, or one the model cannot place: ``window.FIELD: reason``."""


class Georeference(Protocol):
    """Model metres (from the centre of the model's south-west cell) to and from WGS84."""

    def to_model(self, lon: float, lat: float, field: str) -> tuple[float, float]:
        """Model metres of a WGS84 point; WindowError naming ``field`` if it has none."""

    def to_wgs84(self, x: float, y: float) -> tuple[float, float]:
        """(lon, lat) WGS84 degrees of a point in model metres."""


@dataclass(frozen=True)
class Area:
    """The cells of a model read for a world, and where they lie on the model."""

    heights: np.ndarray
    """(ny, nx) metres, rows south to north, NaN where unknown: the cells covering the area."""
    cell: tuple[float, float]
    """(east, north) cell size, m."""
    notes: tuple[str, ...]
    model_cells: tuple[int, int]
    """(nx, ny) of the whole model's grid in metres."""
    origin: tuple[float, float]
    """Model metres of heights[0, 0]."""
    window: tuple[float, float, float, float] | None
    """(x0, y0, width, depth) model metres of the window asked for; None: the whole model."""
    centre: str = ""
    """How the window's centre was given, when in degrees."""
    georef: Georeference | None = None
    """Where the model lies on the Earth; None for a model without a coordinate system."""

    @property
    def model_size(self) -> tuple[float, float]:
        return ((self.model_cells[0] - 1) * self.cell[0], (self.model_cells[1] - 1) * self.cell[1])

    @property
    def box(self) -> tuple[float, float, float, float]:
        """(x0, y0, width, depth) model metres of the area flown."""
        return self.window if self.window is not None else (0.0, 0.0, *self.model_size)


def place(window, model_cells: tuple[int, int], cell: tuple[float, float],
          centre_xy: tuple[float, float] | None = None, centre: str = ""
          ) -> tuple[float, float, float, float]:
    """(x0, y0, width, depth) model metres of ``window`` (sitl.terrain.settings.WindowSettings)
    on a model of ``model_cells`` cells of ``cell`` m, whose centre is ``centre_xy`` (model
    metres of a centre given in degrees, said as ``centre``) or the window's [x, y] or the
    model's centre. Raises WindowError when it is not wholly on the model."""
    width, depth = (model_cells[0] - 1) * cell[0], (model_cells[1] - 1) * cell[1]
    if centre_xy is None:
        centre_xy = (width / 2, depth / 2) if window.center is None else window.center
    x, y = centre_xy
    on_model = (f"the elevation model (x 0 .. {width:.6g}, y 0 .. {depth:.6g} m from its "
                "south-west corner)")
    said = f"{centre} (x {x:.6g}, y {y:.6g} m)" if centre else f"({x:.6g}, {y:.6g})"
    if not (-_EPS <= x <= width + _EPS and -_EPS <= y <= depth + _EPS):
        raise WindowError(f"window.center: {said} is off {on_model}")
    w, d = window.size
    x0, y0 = x - w / 2, y - d / 2
    cx = x0 if x0 < -_EPS else x0 + w if x0 + w > width + _EPS else None
    cy = y0 if y0 < -_EPS else y0 + d if y0 + d > depth + _EPS else None
    if cx is not None or cy is not None:
        corner = (x if cx is None else cx, y if cy is None else cy)
        raise WindowError(
            f"window.size: a {w:g} x {d:g} m window centred at {said} reaches "
            f"({corner[0]:.6g}, {corner[1]:.6g}), off {on_model}"
        )
    return (max(x0, 0.0), max(y0, 0.0), min(w, width), min(d, depth))


def covering(box: tuple[float, float, float, float], cell: tuple[float, float],
             model_cells: tuple[int, int]) -> tuple[int, int, int, int]:
    """(i0, i1, j0, j1): the rows (south to north) and columns, inclusive, of the model's
    cells whose bilinear heights cover ``box``."""
    x0, y0, w, d = box
    j0 = max(0, math.floor(x0 / cell[0] + 1e-6))
    j1 = min(model_cells[0] - 1, math.ceil((x0 + w) / cell[0] - 1e-6))
    i0 = max(0, math.floor(y0 / cell[1] + 1e-6))
    i1 = min(model_cells[1] - 1, math.ceil((y0 + d) / cell[1] - 1e-6))
    return i0, max(i1, i0 + 1), j0, max(j1, j0 + 1)


def crop(heights: np.ndarray, cell: tuple[float, float], notes: tuple[str, ...], window
         ) -> Area:
    """The Area of a model read whole (.npy, .asc): its window's cells, or all of them."""
    model_cells = (heights.shape[1], heights.shape[0])
    if window is None:
        return Area(heights, cell, notes, model_cells, (0.0, 0.0), None)
    if window.center is not None and not isinstance(window.center, tuple):
        raise WindowError(
            "window.center: {lat, lon} needs a model with a coordinate system (a GeoTIFF or "
            "another GDAL format with a CRS); give [x, y] metres from its south-west corner"
        )
    box = place(window, model_cells, cell)
    i0, i1, j0, j1 = covering(box, cell, model_cells)
    return Area(heights[i0:i1 + 1, j0:j1 + 1], cell, notes, model_cells,
                (j0 * cell[0], i0 * cell[1]), box)


def nodata_values(nodata: tuple[float, ...]) -> list[float]:
    """The values that mark nodata in heights read as float64: each as given and as a
    float32 file holds it (-3.4028235e38 there is -3.4028234663852886e38 here)."""
    return [v for x in nodata for v in (x, float(np.float32(x)))]
