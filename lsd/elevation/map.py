"""A robot-centric 2.5D elevation grid with per-cell Kalman fusion of height measurements.

The grid is a fixed-size square window of cells aligned with the world: cell ``[i, j]`` covers
world x in ``[(ox + i) * r, (ox + i + 1) * r)`` and y in ``[(oy + j) * r, (oy + j + 1) * r)``,
where ``(ox, oy)`` is :attr:`ElevationMap.origin_index` and ``r`` the resolution. Axis 0 is x
(east), axis 1 is y (north). Recentring moves the window by whole cells, so a world point
always falls in the same world cell and the estimates of the overlap are kept unchanged.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit

from lsd.elevation.cell_fusion import forget_cells, fuse_cells
from lsd.elevation.settings import ElevationMapSettings
from lsd.plane_fit import copy_where

_EMPTY = np.zeros(0, np.float32)  # no per-point counts


def _shift(grid: np.ndarray, di: int, dj: int, fill: float) -> None:
    """``grid[i, j] = grid[i + di, j + dj]`` in place where that exists, ``fill`` elsewhere.

    One overlapping copy of the flat (C-ordered) grid moves every cell by ``di`` rows and
    ``dj`` columns (numpy copies overlapping 1-D slices in the safe direction, without a
    temporary); the cells it brings in from the neighbouring row, or from beyond the ends,
    lie in the strips that entered the window, which are then filled. No new arrays: a
    fresh grid per move costs its allocation and page faults."""
    n0, n1 = grid.shape
    if abs(di) >= n0 or abs(dj) >= n1:
        grid.fill(fill)
        return
    flat = grid.reshape(-1)
    size, offset = n0 * n1, di * n1 + dj
    if offset > 0:
        flat[: size - offset] = flat[offset:]
    elif offset < 0:
        flat[-offset:] = flat[: size + offset]
    if di > 0:
        grid[n0 - di :] = fill
    elif di < 0:
        grid[:-di] = fill
    if dj > 0:
        grid[:, n1 - dj :] = fill
    elif dj < 0:
        grid[:, :-dj] = fill


@njit(cache=True, nogil=True, error_model="numpy")
def _finite_bounds(grid):
    """(i0, i1, j0, j1) of :meth:`ElevationMap.observed_bounds` (i0 >= i1 when no cell is
    finite), each row read from its ends only up to its first and last finite cell (a
    map's rows are mostly observed or not at all)."""
    n0, n1 = grid.shape
    i0, i1, j0, j1 = n0, 0, n1, 0
    for i in range(n0):
        first = 0
        while first < n1 and not np.isfinite(grid[i, first]):
            first += 1
        if first == n1:
            continue
        last = n1 - 1
        while not np.isfinite(grid[i, last]):
            last -= 1
        i0 = min(i0, i)
        i1 = i + 1
        j0 = min(j0, first)
        j1 = max(j1, last + 1)
    return i0, i1, j0, j1


class ElevationMap:
    """Fused terrain heights in a square window that follows the vehicle.

    Attributes:
        settings: the :class:`ElevationMapSettings`.
        mean: (n, n) float64 fused height, ENU z metres; NaN where unobserved.
        top: (n, n) float64 fused top of the cell (90th percentile of its points less the
            noise's share), ENU z metres (NaN where unobserved): catches rocks smaller than
            a cell, which the mean averages away.
        variance: (n, n) float64 variance of ``mean``, m^2; inf where unobserved.
        closest: (n, n) float64 smallest height of the camera above the cell at which the
            cell was measured, metres; inf where unobserved (or the camera was unknown).
        last_update: (n, n) float64 clock seconds of the last measurement; -inf if none.
        origin_index: (2,) int64 world cell index (x, y) of cell ``[0, 0]``.
    """

    def __init__(self, settings: ElevationMapSettings | None = None) -> None:
        self.settings = settings or ElevationMapSettings()
        n = self.settings.cells
        self.mean = np.full((n, n), np.nan)
        self.top = np.full((n, n), np.nan)
        self.variance = np.full((n, n), np.inf)
        self.closest = np.full((n, n), np.inf)
        self.last_update = np.full((n, n), -np.inf)
        self.origin_index = np.zeros(2, dtype=np.int64)
        self._centred = False
        # No observed cell was last measured before this (a lower bound, so that
        # forgetting can tell cheaply when nothing is old enough yet).
        self._oldest = math.inf
        self._fuse_scratch: dict[tuple[np.dtype, np.dtype], tuple] = {}

    @property
    def resolution(self) -> float:
        return self.settings.resolution

    @property
    def shape(self) -> tuple[int, int]:
        return self.mean.shape

    @property
    def observed(self) -> np.ndarray:
        """(n, n) bool: cells holding an estimate."""
        return np.isfinite(self.mean)

    def observed_bounds(self) -> tuple[int, int, int, int] | None:
        """(i0, i1, j0, j1): the smallest box ``[i0, i1) x [j0, j1)`` of cells holding every
        observed cell, or None when no cell is observed."""
        i0, i1, j0, j1 = _finite_bounds(self.mean)
        return None if i0 >= i1 else (int(i0), int(i1), int(j0), int(j1))

    def cell_centres(self) -> tuple[np.ndarray, np.ndarray]:
        """World x of the cell centres along axis 0 and y along axis 1, each (n,) metres."""
        r = self.resolution
        n0, n1 = self.shape
        x = (self.origin_index[0] + np.arange(n0) + 0.5) * r
        y = (self.origin_index[1] + np.arange(n1) + 0.5) * r
        return x, y

    def cell_of(
        self, x: np.ndarray | float, y: np.ndarray | float
    ) -> tuple[np.ndarray, np.ndarray]:
        """Grid indices (i, j) of world positions (may lie outside the window)."""
        r = self.resolution
        i = np.floor(np.asarray(x, dtype=np.float64) / r).astype(np.int64) - self.origin_index[0]
        j = np.floor(np.asarray(y, dtype=np.float64) / r).astype(np.int64) - self.origin_index[1]
        return i, j

    def height_at(self, x: np.ndarray | float, y: np.ndarray | float) -> np.ndarray:
        """Fused height at world positions, NaN outside the window or where unobserved."""
        i, j = self.cell_of(x, y)
        n0, n1 = self.shape
        inside = (i >= 0) & (i < n0) & (j >= 0) & (j < n1)
        out = np.full(np.shape(i), np.nan)
        out[inside] = self.mean[i[inside], j[inside]]
        return out

    def recentre(self, x: float, y: float, slack: float = 0.0) -> int:
        """Move the window by whole cells so that world (x, y) lies in its centre cell.

        Cells that leave the window are forgotten; cells that enter it are unobserved.
        With ``slack`` (metres), the window stays put while (x, y) is no farther than that
        from its centre cell along either axis (each move copies the whole grid).
        Returns how many cells the window moved (Chebyshev distance).
        """
        n0, n1 = self.shape
        target = np.array(
            [math.floor(x / self.resolution) - n0 // 2, math.floor(y / self.resolution) - n1 // 2],
            dtype=np.int64,
        )
        if not self._centred:
            self.origin_index = target
            self._centred = True
            return 0
        di, dj = (int(v) for v in target - self.origin_index)
        if max(abs(di), abs(dj)) <= slack / self.resolution:
            return 0
        for grid, fill in ((self.mean, np.nan), (self.top, np.nan), (self.variance, np.inf),
                           (self.closest, np.inf), (self.last_update, -np.inf)):
            _shift(grid, di, dj, fill)
        self.origin_index = target
        return max(abs(di), abs(dj))

    def fuse(
        self,
        points: np.ndarray,
        variance: np.ndarray,
        now: float,
        camera_height: float | None = None,
    ) -> int:
        """Fuse height measurements into their cells.

        All points falling in one cell are first combined by inverse-variance weighting
        (one measurement per cell and call, its variance floored at ``min_sigma**2``), which
        then updates the cell estimate as a 1-D Kalman filter. A measurement farther than
        ``outlier_gate`` sigmas from the estimate is not averaged in: the cell keeps
        whichever of the two has the smaller variance (a close-range look replaces a
        far one; a far noisy look cannot spoil a close one). The cell's top (90th percentile
        of its points less the noise's share) is fused with the same gains.

        Args:
            points: (N, 3) world points, ENU metres.
            variance: (N,) variance of each point's height, m^2, > 0.
            now: clock seconds of the measurements.
            camera_height: ENU z of the camera that measured them, metres, or None; it
                updates :attr:`closest`.

        Returns:
            the number of points that fell inside the window and were fused.
        """
        points = np.asarray(points)
        return self.fuse_columns(
            points[:, 0], points[:, 1], points[:, 2], variance, now, camera_height
        )

    def fuse_columns(
        self,
        x: np.ndarray,
        y: np.ndarray,
        z: np.ndarray,
        variance: np.ndarray,
        now: float,
        camera_height: float | None = None,
        count: np.ndarray | None = None,
    ) -> int:
        """:meth:`fuse` with the points as separate (N,) coordinate arrays (float32 is
        fine: cells are found relative to the window), each point optionally standing for
        ``count`` measurements already combined (a block of pixels: ``z`` their
        inverse-variance weighted mean, ``variance`` the variance of that mean).

        Returns:
            the number of measurements (sum of ``count``) inside the window, fused.
        """
        n0, n1 = self.shape
        if len(x) == 0:
            return 0
        x = np.ascontiguousarray(x)
        y = np.ascontiguousarray(y)
        z = np.ascontiguousarray(z)
        variance = np.ascontiguousarray(variance)
        # Scalars in the precision numpy 2 would compute with them against each array.
        xt, yt = x.dtype.type, y.dtype.type
        fused, inside = fuse_cells(
            x, y, z, variance,
            _EMPTY if count is None else np.ascontiguousarray(count),
            xt(1.0 / self.resolution), xt(self.origin_index[0]),
            yt(1.0 / self.resolution), yt(self.origin_index[1]),
            variance.dtype.type(1.0),
            self.mean.reshape(-1), self.variance.reshape(-1), self.top.reshape(-1),
            self.last_update.reshape(-1), self.closest.reshape(-1),
            n0, n1, float(now), math.nan if camera_height is None else float(camera_height),
            self.settings.min_sigma**2, self.settings.outlier_gate**2,
            *self._scratch(len(x), np.result_type(variance, z), z.dtype),
        )
        if inside:
            self._oldest = min(self._oldest, now)
        return int(fused)

    def _scratch(self, points: int, terms: np.dtype, heights: np.dtype) -> tuple:
        """Work space of :func:`fuse_cells` for ``points`` points whose weighted terms have
        the precision ``terms`` and heights ``heights``, kept between calls."""
        n0, n1 = self.shape
        got = self._fuse_scratch.get((terms, heights))
        if got is None or got[0].shape[0] < points:
            size = max(points, 1 << 16)
            got = self._fuse_scratch[(terms, heights)] = (
                np.empty(size, np.int32), np.empty((3, size), terms),
                np.empty(size, heights), np.zeros(n0 * n1, np.int32),
                np.empty((2, n0 * n1), np.int32),
            )
        return got

    def forget_older_than(self, now: float) -> int:
        """Forget cells last measured more than ``max_age`` seconds before ``now``.

        Returns the number of cells forgotten.
        """
        cutoff = now - self.settings.max_age
        if cutoff <= self._oldest:
            return 0
        count, oldest = forget_cells(
            self.mean.reshape(-1), self.top.reshape(-1), self.variance.reshape(-1),
            self.closest.reshape(-1), self.last_update.reshape(-1), cutoff,
        )
        # Every cell kept was measured at or after the cutoff; the earliest of them bounds
        # when the next one can be forgotten (until then nothing need be scanned).
        self._oldest = max(cutoff, oldest)
        return int(count)

    def clear(self) -> None:
        """Forget everything (the window stays where it is)."""
        self._oldest = math.inf
        self.mean.fill(np.nan)
        self.top.fill(np.nan)
        self.variance.fill(np.inf)
        self.closest.fill(np.inf)
        self.last_update.fill(-np.inf)


def pooled_level(
    mean: np.ndarray,
    variance: np.ndarray,
    top: np.ndarray,
    closest: np.ndarray,
    factor: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A coarser level of a map window: ``factor`` x ``factor`` blocks of cells pooled.

    Each block's observed cells are combined by inverse-variance weighting, as the map
    fuses measurements: the pooled height and top are the weighted means of the cells'
    heights and tops and the pooled variance is ``1 / sum(1 / variance)``. The plain mean
    of the cells' variances is kept apart (what one cell of the block is worth, for the
    reported uncertainty), and the block's ``closest`` is its largest finite one (a block
    is only as closely seen as its farthest-seen cell).

    Args:
        mean, variance, top, closest: (n, m) window of an :class:`ElevationMap`'s grids
            (NaN / inf where unobserved), n and m multiples of ``factor``.
        factor: block side, cells.

    Returns:
        mean, variance, top, cell_variance, closest: (n / factor, m / factor) float64
        (NaN, inf, NaN, inf and 0 where the block holds no observed cell).
    """
    n0, n1 = mean.shape
    shape = (n1 // factor, n0 // factor)  # OpenCV's (width, height)
    hidden = np.isnan(mean)
    if hidden.all():
        empty = np.full((n0 // factor, n1 // factor), np.nan)
        inf = np.full_like(empty, np.inf)
        return empty, inf, empty.copy(), inf.copy(), np.zeros_like(empty)
    # Heights from a reference keep the sums exact enough in single precision: the first
    # observed cell's (row by row).
    ref = float(mean.flat[int(np.argmin(hidden))])
    weight, z, t, var, unseen = _weighted_terms(mean, variance, top, ref)

    def block_mean(grid: np.ndarray) -> np.ndarray:
        # INTER_AREA with a whole-number factor is exactly the block mean.
        return cv2.resize(grid, shape, interpolation=cv2.INTER_AREA).astype(np.float64)

    sum_w = block_mean(weight)
    count = 1.0 - block_mean(unseen)
    with np.errstate(divide="ignore", invalid="ignore"):
        pooled_mean = block_mean(z) / sum_w
        pooled_top = block_mean(t) / sum_w
        pooled_var = 1.0 / (sum_w * float(factor * factor))
        cell_var = block_mean(var) / count
    pooled_mean += ref
    pooled_top += ref
    empty = count < 0.5 / (factor * factor)
    copy_where(pooled_mean, np.nan, empty)
    copy_where(pooled_top, np.nan, empty)
    copy_where(pooled_var, np.inf, empty)
    copy_where(cell_var, np.inf, empty)
    np.maximum(pooled_top, pooled_mean, out=pooled_top)
    return pooled_mean, pooled_var, pooled_top, cell_var, _block_looks(closest, factor)


@njit(cache=True, nogil=True, error_model="numpy")
def _weighted_terms(mean, variance, top, ref):
    """The single-precision grids :func:`pooled_level` averages over blocks, in one pass
    with numpy's operations: the weight ``1 / variance``, the weighted heights and tops from
    ``ref`` (0 where NaN before weighting), the variance (0 where unobserved) and the
    unobserved flag."""
    n0, n1 = mean.shape
    f32 = np.float32
    out = np.empty((5, n0, n1), f32)
    f_ref = f32(ref)
    zero = f32(0.0)
    for i in range(n0):
        for j in range(n1):
            v = f32(variance[i, j])
            w = f32(1.0) / v
            z = f32(mean[i, j]) - f_ref
            t = f32(top[i, j]) - f_ref
            hidden = np.isnan(mean[i, j])
            out[0, i, j] = w
            out[1, i, j] = (zero if z != z else z) * w
            out[2, i, j] = (zero if t != t else t) * w
            out[3, i, j] = zero if hidden else v
            out[4, i, j] = f32(1.0) if hidden else zero
    return out[0], out[1], out[2], out[3], out[4]


@njit(cache=True, nogil=True, error_model="numpy")
def cell_looks(closest: np.ndarray) -> np.ndarray:
    """(n, m) float32 ``closest`` (a map window's), unobserved (infinite) cells as 0 (no
    say in a largest look): ``closest.astype(np.float32)`` with its infinities zeroed, in
    one pass."""
    n0, n1 = closest.shape
    out = np.empty((n0, n1), np.float32)
    for i in range(n0):
        for j in range(n1):
            v = np.float32(closest[i, j])
            out[i, j] = np.float32(0.0) if np.isinf(v) else v
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def _block_looks(closest: np.ndarray, factor: int) -> np.ndarray:
    """(n / factor, m / factor) float64: each block's largest ``closest`` in single
    precision, unobserved (infinite) cells counting as 0 and NaN winning (numpy's max).

    Each band of ``factor`` rows is reduced down its columns first (vectorised), then
    across each block's columns. A maximum is the same in any order but for the sign of
    a zero: if the window holds a -0, the blocks are taken in row-major order, the first
    of equals kept, as they always were."""
    n0, n1 = closest.shape
    m0, m1 = n0 // factor, n1 // factor
    width = m1 * factor
    column = np.empty(width, np.float32)
    hidden = np.empty(width, np.bool_)
    out = np.empty((m0, m1))
    zero = np.float32(0.0)
    signed_zero = False
    for a in range(m0):
        column[:] = -np.inf
        hidden[:] = False
        for i in range(a * factor, (a + 1) * factor):
            for j in range(width):
                v = np.float32(closest[i, j])
                v = zero if np.isinf(v) else v
                signed_zero |= v == 0 and np.signbit(v)
                hidden[j] |= v != v
                column[j] = v if v > column[j] else column[j]
        for b in range(m1):
            best = np.float32(-np.inf)
            nan = False
            for j in range(b * factor, (b + 1) * factor):
                best = column[j] if column[j] > best else best
                nan |= hidden[j]
            out[a, b] = np.nan if nan else best
    return _block_looks_in_order(closest, factor) if signed_zero else out


@njit(cache=True, nogil=True, error_model="numpy")
def _block_looks_in_order(closest: np.ndarray, factor: int) -> np.ndarray:
    """:func:`_block_looks`, each block in row-major order."""
    n0, n1 = closest.shape
    out = np.zeros((n0 // factor, n1 // factor))
    for a in range(n0 // factor):
        for b in range(n1 // factor):
            best = np.float32(-np.inf)
            for i in range(a * factor, (a + 1) * factor):
                for j in range(b * factor, (b + 1) * factor):
                    v = np.float32(closest[i, j])
                    if np.isinf(v):
                        v = np.float32(0.0)
                    if v != v or best != best:
                        best = np.float32(np.nan)
                    elif v > best:
                        best = v
            out[a, b] = best
    return out
