"""The terrain world as a regular height grid in the local ENU frame."""

from __future__ import annotations

import math

import numpy as np


class Terrain:
    """A height field h(x, y) sampled on a regular grid (local ENU metres, z up).

    Row ``i`` of :attr:`grid` runs along y (north), column ``j`` along x (east); the centre of
    cell ``(i, j)`` is at ``(origin[0] + j * cell_size, origin[1] + i * cell_size)``.
    Between cell centres the surface is bilinear; outside the grid it continues with the edge
    value. Home (0, 0) is at ground level z = 0 in the worlds :func:`make_terrain` builds.

    A terrain with a ``known`` mask is an elevation model read from a file: it has ground
    only on its grid where ``known`` is True (:meth:`has_ground`). Sensors get no return
    elsewhere (off the model, nodata cells); :attr:`grid` holds the nearest known height
    there only so that rays march through a continuous surface.

    Args:
        grid: (ny, nx) heights in metres (stored as float32).
        cell_size: grid spacing in metres.
        origin: (x0, y0) ENU metres of the centre of cell ``grid[0, 0]``.
        kind: name of the world kind that produced it ("flat", "mars", ...).
        known: (ny, nx) bool, True where the model has a height; None: ground everywhere
            (a procedural world, continued with its edge values beyond the grid).
    """

    moving = None
    """:class:`sitl.terrain.moving.MovingObstacles` of the world, or None (nothing moves):
    sensors and the ground truth ask it where everything is at the time they look."""

    def __init__(
        self,
        grid: np.ndarray,
        cell_size: float,
        origin: tuple[float, float] = (0.0, 0.0),
        kind: str = "custom",
        known: np.ndarray | None = None,
    ) -> None:
        grid = np.ascontiguousarray(grid, dtype=np.float32)
        if grid.ndim != 2 or min(grid.shape) < 2:
            raise ValueError(f"grid: need a 2-D array of at least 2 x 2 cells, got {grid.shape}")
        if not np.all(np.isfinite(grid)):
            raise ValueError("grid: heights must be finite")
        if not (np.isfinite(cell_size) and cell_size > 0):
            raise ValueError(f"cell_size: must be a positive number, got {cell_size}")
        self.grid = grid
        self.cell_size = float(cell_size)
        self.origin = (float(origin[0]), float(origin[1]))
        self.kind = kind
        self._flat = grid.ravel()
        if known is not None:
            known = np.asarray(known, dtype=bool)
            if known.shape != grid.shape:
                raise ValueError(f"known: shape {known.shape} differs from the grid's")
        self.known = known

    def has_ground(self, x, y) -> np.ndarray | bool:
        """True where (x, y) has ground: everywhere on a procedural world; on an elevation
        model (``known`` given) only within :attr:`extent` on a known cell (nearest)."""
        if self.known is None:
            shape = np.broadcast_shapes(np.shape(x), np.shape(y))
            return True if shape == () else np.ones(shape, dtype=bool)
        x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        inside = np.asarray(self.contains(x, y)) & np.isfinite(x) & np.isfinite(y)
        x0, y0 = self.origin
        row, col = self.index(np.where(inside, x, x0), np.where(inside, y, y0))
        ground = inside & self.known[row, col]
        return bool(ground) if ground.ndim == 0 else ground

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx) cells."""
        return self.grid.shape  # type: ignore[return-value]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, xmax, ymin, ymax) ENU metres spanned by the cell centres."""
        ny, nx = self.grid.shape
        x0, y0 = self.origin
        return (x0, x0 + (nx - 1) * self.cell_size, y0, y0 + (ny - 1) * self.cell_size)

    def contains(self, x, y) -> np.ndarray | bool:
        """True where (x, y) lies within :attr:`extent`."""
        xmin, xmax, ymin, ymax = self.extent
        x = np.asarray(x)
        y = np.asarray(y)
        inside = (x >= xmin) & (x <= xmax) & (y >= ymin) & (y <= ymax)
        return bool(inside) if inside.ndim == 0 else inside

    def index(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """Nearest cell (row, column) of ENU points, clipped to the grid; int arrays."""
        ny, nx = self.grid.shape
        col = np.rint((np.asarray(x, dtype=np.float64) - self.origin[0]) / self.cell_size)
        row = np.rint((np.asarray(y, dtype=np.float64) - self.origin[1]) / self.cell_size)
        return (
            np.clip(row, 0, ny - 1).astype(np.intp),
            np.clip(col, 0, nx - 1).astype(np.intp),
        )

    def coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre coordinates: x (nx,) and y (ny,) in ENU metres."""
        ny, nx = self.grid.shape
        return (
            self.origin[0] + self.cell_size * np.arange(nx),
            self.origin[1] + self.cell_size * np.arange(ny),
        )

    def height(self, x, y) -> np.ndarray:
        """Terrain height (ENU z, metres) at points (x, y): bilinear between cell centres,
        edge value outside the grid. ``x`` and ``y`` broadcast; the result has their
        broadcast shape (float64)."""
        ny, nx = self.grid.shape
        fx = (np.asarray(x, dtype=np.float64) - self.origin[0]) / self.cell_size
        fy = (np.asarray(y, dtype=np.float64) - self.origin[1]) / self.cell_size
        fx, fy = np.broadcast_arrays(fx, fy)
        # NaN coordinates give NaN heights instead of garbage indices.
        bad = ~(np.isfinite(fx) & np.isfinite(fy))
        fx = np.clip(np.where(bad, 0.0, fx), 0.0, nx - 1)
        fy = np.clip(np.where(bad, 0.0, fy), 0.0, ny - 1)
        j = np.minimum(fx.astype(np.intp), nx - 2)
        i = np.minimum(fy.astype(np.intp), ny - 2)
        tx = fx - j
        ty = fy - i
        k = i * nx + j
        g = self._flat
        h00 = g[k]
        h01 = g[k + 1]
        h10 = g[k + nx]
        h11 = g[k + nx + 1]
        top = h00 + tx * (h01 - h00)
        bottom = h10 + tx * (h11 - h10)
        h = top + ty * (bottom - top)
        if bad.any():
            h = np.where(bad, np.nan, h)
        return h

    def height_at(self, x: float, y: float) -> float:
        """:meth:`height` at one point, as a float: the same arithmetic (the corner
        differences in single precision, the rest in double) without building arrays, for
        the simulator's per-step lookups."""
        fx = (float(x) - self.origin[0]) / self.cell_size
        fy = (float(y) - self.origin[1]) / self.cell_size
        if not (math.isfinite(fx) and math.isfinite(fy)):
            return math.nan
        ny, nx = self.grid.shape
        fx = min(max(fx, 0.0), float(nx - 1))
        fy = min(max(fy, 0.0), float(ny - 1))
        j = min(int(fx), nx - 2)
        i = min(int(fy), ny - 2)
        tx = fx - j
        ty = fy - i
        k = i * nx + j
        g = self._flat
        h00, h01, h10, h11 = g[k], g[k + 1], g[k + nx], g[k + nx + 1]
        top = float(h00) + tx * float(h01 - h00)
        bottom = float(h10) + tx * float(h11 - h10)
        return top + ty * (bottom - top)

    def window(self, region: tuple[float, float, float, float]) -> tuple[slice, slice]:
        """(row slice, column slice) of the cells whose centres lie in
        ``region = (xmin, xmax, ymin, ymax)`` (clipped to the grid; may be empty)."""
        xmin, xmax, ymin, ymax = region
        ny, nx = self.grid.shape
        c0 = int(np.clip(np.ceil((xmin - self.origin[0]) / self.cell_size - 1e-9), 0, nx))
        c1 = int(np.clip(np.floor((xmax - self.origin[0]) / self.cell_size + 1e-9) + 1, 0, nx))
        r0 = int(np.clip(np.ceil((ymin - self.origin[1]) / self.cell_size - 1e-9), 0, ny))
        r1 = int(np.clip(np.floor((ymax - self.origin[1]) / self.cell_size + 1e-9) + 1, 0, ny))
        return slice(r0, max(r0, r1)), slice(c0, max(c0, c1))

    def __repr__(self) -> str:
        xmin, xmax, ymin, ymax = self.extent
        return (
            f"Terrain(kind={self.kind!r}, shape={self.grid.shape}, cell_size={self.cell_size}, "
            f"extent=({xmin:.1f}, {xmax:.1f}, {ymin:.1f}, {ymax:.1f}))"
        )
