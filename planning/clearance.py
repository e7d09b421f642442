"""How high a vehicle must stay over each cell of an elevation grid: the highest obstacle top
(raised by its uncertainty) within the vehicle's radius, unobserved cells and everything outside
the grid never passable.

Three ways to the same guarantee, for three uses: the whole grid (:func:`clearance_grid`), a
few cells only (:func:`clearance_at`, for checking a line or a trajectory without building the
grid), and a coarser grid whose every cell is at least as high as any fine cell it covers
(:func:`pooled_clearance`, for a cheaper graph search).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np


def obstacle_height(top: np.ndarray, variance: np.ndarray, k_sigma: float) -> np.ndarray:
    """``top + k_sigma * sqrt(variance)``, +inf where ``top`` is unobserved (NaN); any shape."""
    top = np.asarray(top, dtype=np.float64)
    sigma = np.sqrt(np.where(np.isfinite(variance), variance, 0.0))
    return np.where(np.isfinite(top), top + k_sigma * sigma, np.inf)


class ObstacleHeights:
    """:func:`obstacle_height` of a map, computed only where it is asked for until the whole
    grid is (a straight approach looks at a few hundred cells of tens of thousands)."""

    def __init__(self, top: np.ndarray, variance: np.ndarray, k_sigma: float) -> None:
        self.top = np.asarray(top, dtype=np.float64)
        self.variance = np.asarray(variance, dtype=np.float64)
        self.k_sigma = float(k_sigma)
        self.shape = self.top.shape
        self._grid: np.ndarray | None = None

    def grid(self) -> np.ndarray:
        if self._grid is None:
            self._grid = obstacle_height(self.top, self.variance, self.k_sigma)
        return self._grid

    def at(self, flat: np.ndarray) -> np.ndarray:
        """Heights at the cells of flat (row-major) indices ``flat``."""
        if self._grid is not None:
            return self._grid.reshape(-1).take(flat)
        top, variance = self.top.reshape(-1).take(flat), self.variance.reshape(-1).take(flat)
        return obstacle_height(top, variance, self.k_sigma)


def clearance_grid(
    top: np.ndarray,
    variance: np.ndarray,
    resolution: float,
    radius: float,
    k_sigma: float = 2.0,
) -> np.ndarray:
    """The altitude (ENU z, m) a vehicle of ``radius`` must stay above over each cell.

    Args:
        top: (n0, n1) obstacle top per cell, ENU z metres; NaN where unobserved.
        variance: (n0, n1) variance of ``top``, m^2 (inf where unobserved).
        resolution: cell size, m.
        radius: the vehicle's radius plus any lateral margin, m: each cell takes the highest
            top within this distance (a disc footprint).
        k_sigma: standard deviations added to each top for its uncertainty.

    Returns:
        (n0, n1) float64: the highest ``top + k_sigma * sqrt(variance)`` within ``radius`` of
        each cell; +inf where any cell of that disc is unobserved.
    """
    return disc_maximum(obstacle_height(top, variance, k_sigma), radius / resolution)


def disc_maximum(grid: np.ndarray, reach: float) -> np.ndarray:
    """The highest value within ``reach`` cells (centre to centre) of each cell; +inf outside
    the grid.

    The same values as :func:`scipy.ndimage.maximum_filter` with the disc footprint, built
    from shifted whole-array maxima instead of visiting the footprint for every cell: the
    running maximum over each row's half-width ``w`` grows from ``w - 1`` by one shift each way,
    and the disc is the maximum of the rows ``di`` of half-width ``w(|di|)``.
    """
    cells = int(math.floor(reach + 1e-9))
    grid = np.asarray(grid, dtype=np.float64)
    if cells <= 0:
        return grid.copy()
    n0, n1 = grid.shape
    # Half-width of the disc's row at each vertical offset (non-increasing).
    offsets = np.arange(cells + 1)
    width = np.floor(np.sqrt(np.maximum(reach**2 - offsets**2, 0.0)) + 1e-9).astype(int)
    # Outside the grid is unknown too: pad with +inf rather than repeating the edge.
    padded = np.pad(grid, cells, mode="constant", constant_values=np.inf)
    # Row-wise running maxima on the flattened grid (contiguous, so fast): a shift crosses
    # into the next row only in the padding, which no cell of the grid reaches.
    rows = [padded.reshape(-1)]
    for _ in range(int(width.max())):
        previous = rows[-1]
        wider = previous.copy()
        np.maximum(wider[1:], previous[:-1], out=wider[1:])
        np.maximum(wider[:-1], previous[1:], out=wider[:-1])
        rows.append(wider)
    rows = [r.reshape(padded.shape) for r in rows]
    out = rows[width[0]][cells : cells + n0].copy()
    for di in range(1, cells + 1):
        band = rows[width[di]]
        np.maximum(out, band[cells + di : cells + di + n0], out=out)
        np.maximum(out, band[cells - di : cells - di + n0], out=out)
    return out[:, cells : cells + n1].copy()




@lru_cache(maxsize=16)
def disc_offsets(reach: float) -> np.ndarray:
    """(K, 2) int64 cell offsets whose centres lie within ``reach`` cells of the origin
    (read-only: shared between calls)."""
    cells = int(math.floor(reach + 1e-9))
    d = np.arange(-cells, cells + 1)
    di, dj = np.meshgrid(d, d, indexing="ij")
    inside = np.hypot(di, dj) <= reach + 1e-9
    offsets = np.stack([di[inside], dj[inside]], axis=1).astype(np.int64)
    offsets.flags.writeable = False
    return offsets


def clearance_at(
    height: np.ndarray | ObstacleHeights, cells: np.ndarray, reach: float
) -> np.ndarray:
    """The values of ``disc_maximum(height, reach)`` at ``cells`` only (N, 2), each the highest
    ``height`` within ``reach`` cells; +inf for a cell whose disc leaves the grid."""
    if not isinstance(height, ObstacleHeights):
        height = ObstacleHeights(height, np.zeros_like(height), 0.0)
    n0, n1 = height.shape
    # Every cell outside the grid is +inf alike: fold them onto the ring around it.
    cells = np.asarray(cells, dtype=np.int64).reshape(-1, 2)
    i = np.clip(cells[:, 0], -1, n0)
    j = np.clip(cells[:, 1], -1, n1)
    # Trajectory samples repeat cells many times over: look each cell up once.
    key, back = np.unique((i + 1) * (n1 + 2) + (j + 1), return_inverse=True)
    i, j = key // (n1 + 2) - 1, key % (n1 + 2) - 1
    offsets = disc_offsets(reach)
    ai = i[:, None] + offsets[None, :, 0]
    aj = j[:, None] + offsets[None, :, 1]
    inside = (ai >= 0) & (ai < n0) & (aj >= 0) & (aj < n1)
    flat = np.where(inside, ai * n1 + aj, 0)
    values = np.where(inside, height.at(flat), np.inf)
    return values.max(axis=1)[back.reshape(-1)]


def pooled_clearance(height: np.ndarray, reach: float, factor: int) -> np.ndarray:
    """A grid ``factor`` times coarser than ``height`` whose every cell is at least the
    ``disc_maximum(height, reach)`` of each fine cell it covers (conservative: a coarse cell
    that is free is free at the fine resolution too).

    Each coarse cell first takes the highest fine cell in its block; a fine cell lies within
    ``(factor - 1) / sqrt(2)`` fine cells of its block's centre, so a disc of
    ``reach + sqrt(2) * (factor - 1)`` fine cells around the coarse centre holds every fine
    cell the block's discs reach, and every block those cells fall in.
    """
    if factor <= 1:
        return disc_maximum(height, reach)
    n0, n1 = height.shape
    m0, m1 = -(-n0 // factor), -(-n1 // factor)
    padded = np.full((m0 * factor, m1 * factor), np.inf)
    padded[:n0, :n1] = height
    blocks = padded.reshape(m0, factor, m1, factor).max(axis=(1, 3))
    return disc_maximum(blocks, (reach + math.sqrt(2.0) * (factor - 1)) / factor)
