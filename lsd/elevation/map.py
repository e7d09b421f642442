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

from lsd.elevation.settings import ElevationMapSettings
from lsd.plane_fit import copy_where

TOP_QUANTILE = 0.9  # which percentile of a cell's points is its top
TOP_NOISE_LIFT = 1.2816  # the standard normal's 90th percentile


def _shifted(array: np.ndarray, di: int, dj: int, fill: float) -> np.ndarray:
    """``out[i, j] = array[i + di, j + dj]`` where that exists, ``fill`` elsewhere."""
    n0, n1 = array.shape
    if abs(di) >= n0 or abs(dj) >= n1:
        return np.full_like(array, fill)
    out = np.empty_like(array)
    src_i = slice(max(di, 0), n0 + min(di, 0))
    dst_i = slice(max(-di, 0), n0 - max(di, 0))
    src_j = slice(max(dj, 0), n1 + min(dj, 0))
    dst_j = slice(max(-dj, 0), n1 - max(dj, 0))
    out[dst_i, dst_j] = array[src_i, src_j]
    # Only the strips that entered the window are filled (each cell is written once).
    out[: dst_i.start] = fill
    out[dst_i.stop :] = fill
    out[dst_i, : dst_j.start] = fill
    out[dst_i, dst_j.stop :] = fill
    return out


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
        self.mean = _shifted(self.mean, di, dj, np.nan)
        self.top = _shifted(self.top, di, dj, np.nan)
        self.variance = _shifted(self.variance, di, dj, np.inf)
        self.closest = _shifted(self.closest, di, dj, np.inf)
        self.last_update = _shifted(self.last_update, di, dj, -np.inf)
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
        inv_r = 1.0 / self.resolution
        # Fractional cell indices relative to the window (small numbers, exact enough in
        # single precision); NaN fails every comparison and so falls outside.
        fi = x * inv_r - float(self.origin_index[0])
        fj = y * inv_r - float(self.origin_index[1])
        if len(fi) == 0:
            return 0
        # Four reductions tell when every point is inside (the common case, and NaN
        # makes them fail); only otherwise is each point tested.
        if fi.min() >= 0 and fi.max() < n0 and fj.min() >= 0 and fj.max() < n1:
            n_inside = len(fi)
        else:
            inside = (fi >= 0) & (fi < n0) & (fj >= 0) & (fj < n1)
            n_inside = int(np.count_nonzero(inside))
        if n_inside == 0:
            return 0
        if n_inside < len(fi):
            fi, fj, z, variance = fi[inside], fj[inside], z[inside], variance[inside]
            count = None if count is None else count[inside]
        fused = n_inside if count is None else int(count.sum())
        # Truncation is the floor here: every index left is >= 0.
        flat = fi.astype(np.intp)
        flat *= n1
        flat += fj.astype(np.intp)
        # Sums over the span of cells the points fall in (small when the camera is low).
        base = int(flat.min())
        flat -= base
        span_cells = int(flat.max()) + 1
        weight = 1.0 / variance
        w_sum = np.bincount(flat, weights=weight, minlength=span_cells)
        wz_sum = np.bincount(flat, weights=weight * z, minlength=span_cells)
        v_sum = np.bincount(flat, weights=variance, minlength=span_cells)
        # The cell's top: the 90th percentile of its points, less the 1.28 sigma by which
        # noise alone lifts that percentile. A rock smaller than a cell barely moves the
        # cell's mean but shows in its top. One integer key holds the cell in its high
        # bits and the height, quantised far below any noise, in its low bits: sorting
        # the keys themselves (no argsort) orders the points by cell, then by height.
        cell_bits = max(1, (span_cells - 1).bit_length())
        height_bits = min(50, 62 - cell_bits)
        low = float(z.min())
        span = float(z.max()) - low + 1e-9
        quantum = span / float(1 << height_bits)
        level = ((z - low) * (1.0 / quantum)).astype(np.int64)
        np.minimum(level, (1 << height_bits) - 1, out=level)
        flat <<= height_bits
        flat |= level
        key = np.sort(flat)
        cell_of_key = key >> height_bits
        first = np.flatnonzero(cell_of_key[1:] != cell_of_key[:-1])
        first += 1
        first = np.concatenate(([0], first))
        local = cell_of_key[first]  # cell index less base
        n_points = np.diff(np.append(first, len(key)))
        pick = first + (TOP_QUANTILE * (n_points - 1)).astype(np.int64)
        percentile = low + (key[pick] & ((1 << height_bits) - 1)) * quantum
        w_cell = w_sum[local]
        meas = wz_sum[local] / w_cell
        point_var = v_sum[local] / n_points
        meas_top = np.maximum(percentile - TOP_NOISE_LIFT * np.sqrt(point_var), meas)
        meas_var = np.maximum(1.0 / w_cell, self.settings.min_sigma**2)
        cells = local + base

        mean = self.mean.reshape(-1)
        var = self.variance.reshape(-1)
        top = self.top.reshape(-1)
        mu = mean[cells]
        p = var[cells]  # inf where the cell is new
        old_top = top[cells]
        known = np.isfinite(mu)
        # A new cell starts from its measurement (zero innovation, gain 1 as p is inf).
        unknown = ~known
        copy_where(mu, meas, unknown)
        copy_where(old_top, meas_top, unknown)
        total = p + meas_var
        innovation = meas - mu
        gain = 1.0 - meas_var / total  # p / total, and 1 for a new cell
        outlier = innovation * innovation > self.settings.outlier_gate**2 * total
        if outlier.any():
            # The estimate with the smaller variance wins: gain 1 replaces, 0 keeps.
            closer = meas_var < p
            np.copyto(gain, closer, where=outlier)
            keep = outlier & ~closer
        new_mu = mu + gain * innovation
        new_var = gain * meas_var  # p * meas_var / total; meas_var when replaced
        if outlier.any():
            np.copyto(new_var, p, where=keep)
        new_top = old_top + gain * (meas_top - old_top)
        mean[cells] = new_mu
        top[cells] = np.maximum(new_top, new_mu)
        var[cells] = new_var
        self.last_update.reshape(-1)[cells] = now
        self._oldest = min(self._oldest, now)
        if camera_height is not None:
            closest = self.closest.reshape(-1)
            closest[cells] = np.minimum(closest[cells], np.maximum(camera_height - meas, 0.0))
        return fused

    def forget_older_than(self, now: float) -> int:
        """Forget cells last measured more than ``max_age`` seconds before ``now``.

        Returns the number of cells forgotten.
        """
        cutoff = now - self.settings.max_age
        if cutoff <= self._oldest:
            return 0
        # Every cell kept was measured at or after the cutoff.
        self._oldest = cutoff
        stale = np.isfinite(self.mean) & (self.last_update < cutoff)
        count = int(np.count_nonzero(stale))
        if count:
            self.mean[stale] = np.nan
            self.top[stale] = np.nan
            self.variance[stale] = np.inf
            self.closest[stale] = np.inf
            self.last_update[stale] = -np.inf
        return count

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
    f32 = np.float32
    n0, n1 = mean.shape
    shape = (n1 // factor, n0 // factor)  # OpenCV's (width, height)
    hidden = np.isnan(mean)
    if hidden.all():
        empty = np.full((n0 // factor, n1 // factor), np.nan)
        inf = np.full_like(empty, np.inf)
        return empty, inf, empty.copy(), inf.copy(), np.zeros_like(empty)
    # Heights from a reference keep the sums exact enough in single precision.
    ref = float(mean[~hidden].flat[0])
    var = variance.astype(f32)
    weight = np.divide(f32(1.0), var)  # 0 where unobserved (infinite variance)
    copy_where(var, 0.0, hidden)
    z = np.subtract(mean, ref, dtype=f32)
    t = np.subtract(top, ref, dtype=f32)
    cv2.patchNaNs(z, 0.0)
    cv2.patchNaNs(t, 0.0)
    z *= weight
    t *= weight

    def block_mean(grid: np.ndarray) -> np.ndarray:
        # INTER_AREA with a whole-number factor is exactly the block mean.
        return cv2.resize(grid, shape, interpolation=cv2.INTER_AREA).astype(np.float64)

    sum_w = block_mean(weight)
    count = 1.0 - block_mean(hidden.view(np.uint8).astype(f32))
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
    looks = closest.astype(f32)
    copy_where(looks, 0.0, np.isinf(looks))
    pooled_looks = looks.reshape(n0 // factor, factor, n1 // factor, factor).max(axis=(1, 3))
    return pooled_mean, pooled_var, pooled_top, cell_var, pooled_looks.astype(np.float64)
