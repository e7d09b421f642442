"""A depth frame's back-projection for :meth:`ElevationDetector.integrate` as one compiled
pass (numba): the vectorised version made a dozen single-precision passes over the image
(each ray component, each offset, the ray's length along the optical axis, the height
variance); this kernel computes each pixel's in one go, with the same single-precision
operations in the same order, so the points come out bit for bit the same. The pixel blocks
fused as one point each (:func:`block_points`) likewise: their masked images in one pass,
OpenCV's block means, and the points in one pass."""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit

_F = np.float32


@njit(cache=True, nogil=True, error_model="numpy")
def back_project(depth, placement, sigma, rotation, xn, yn, min_var):
    """Each pixel's offset from the camera and its height variance, single precision.

    Args:
        depth: (H, W) float32 depth; placement: (H, W) float32 depth that places points
            horizontally (the smoothed depth).
        sigma: (H, W) float32 per-pixel depth error, or a (0, 0) array for none (every
            variance is then ``min_var``).
        rotation: (3, 3) float64 camera-to-world rotation.
        xn, yn: (W,) and (H,) float32 normalised image coordinates of columns and rows.
        min_var: float32 floor added to each variance.

    Returns:
        east, north, drop, variance: (H, W) float32; ``east`` and ``north`` are
        ``placement`` times the ray's world x and y, ``drop`` is ``depth`` times its world z.
    """
    height, width = depth.shape
    east = np.empty((height, width), _F)
    north = np.empty((height, width), _F)
    drop = np.empty((height, width), _F)
    variance = np.empty((height, width), _F)
    r = np.empty((3, 3), _F)
    for a in range(3):
        for b in range(3):
            r[a, b] = _F(rotation[a, b])
    has_sigma = sigma.shape[0] > 0
    for i in range(height):
        # The row's part of each ray component: r[., 1] * yn + r[., 2].
        row0 = r[0, 1] * yn[i] + r[0, 2]
        row1 = r[1, 1] * yn[i] + r[1, 2]
        row2 = r[2, 1] * yn[i] + r[2, 2]
        for j in range(width):
            e = placement[i, j] * (r[0, 0] * xn[j] + row0)
            n = placement[i, j] * (r[1, 0] * xn[j] + row1)
            d = depth[i, j] * (r[2, 0] * xn[j] + row2)
            east[i, j] = e
            north[i, j] = n
            drop[i, j] = d
            if has_sigma:
                # The ray error is along the optical axis; its vertical part scales the
                # depth error by |dz| / depth.
                along_axis = e * r[0, 2] + n * r[1, 2]
                along_axis = along_axis + d * r[2, 2]
                v = sigma[i, j] * abs(d)
                v = v / along_axis
                variance[i, j] = v * v + min_var
            else:
                variance[i, j] = min_var
    return east, north, drop, variance


@njit(cache=True, nogil=True, error_model="numpy")
def valid_points(valid, east, north, drop, variance, count):
    """The ``count`` pixels where ``valid`` ((H, W) bool) holds, of the four (H, W) grids,
    in row-major order, each as a (count,) array (``a.reshape(-1)[np.flatnonzero(valid)]``
    for all four in one pass)."""
    x = np.empty(count, east.dtype)
    y = np.empty(count, north.dtype)
    z = np.empty(count, drop.dtype)
    var = np.empty(count, variance.dtype)
    height, width = valid.shape
    k = 0
    for i in range(height):
        for j in range(width):
            if valid[i, j]:
                x[k] = east[i, j]
                y[k] = north[i, j]
                z[k] = drop[i, j]
                var[k] = variance[i, j]
                k += 1
    return x, y, z, var



@njit(cache=True, nogil=True, error_model="numpy")
def median32(sample):
    """``np.median`` of a single-precision array as numpy computes it: the middle value, or
    the two middle ones' single-precision sum halved (NaN when any value is NaN), from a
    partition without numpy's copies, NaN check and mean."""
    n = sample.size
    for k in range(n):
        if np.isnan(sample[k]):
            return np.float32(np.nan)
    half = n // 2
    part = np.partition(sample, half)
    if n % 2:
        return part[half]
    below = part[0]
    for k in range(1, half):
        below = max(below, part[k])
    return (below + part[half]) / np.float32(2.0)


@njit(cache=True, nogil=True, error_model="numpy")
def _block_terms(east, north, drop, variance, valid, planes):
    """The masked images whose block means make the pixel blocks, in one pass (each with
    the array version's single-precision operations): the weight ``1 / variance``, the
    weighted height, east, north and the valid share, zero where a pixel is not valid."""
    zero = _F(0.0)
    for i in range(planes.shape[1]):
        for j in range(planes.shape[2]):
            ok = valid[i, j]
            w = _F(1.0) / variance[i, j]
            w = w if ok else zero
            planes[0, i, j] = w
            planes[1, i, j] = w * drop[i, j] if ok else zero
            planes[2, i, j] = east[i, j] if ok else zero
            planes[3, i, j] = north[i, j] if ok else zero
            planes[4, i, j] = _F(1.0) if ok else zero


@njit(cache=True, nogil=True, error_model="numpy")
def _block_sums_to_points(means, area):
    """The blocks holding a valid pixel (more than half a pixel's share) as points from
    their block means (x, y, z, variance, count as :func:`block_points` returns them)."""
    sums = means.reshape(5, -1)
    out = np.empty((5, sums.shape[1]), _F)
    n = 0
    for b in range(sums.shape[1]):
        count = sums[4, b] * area
        if not count > 0.5:
            continue
        w_sum = sums[0, b] * area
        out[0, n] = (sums[2, b] * area) / count
        out[1, n] = (sums[3, b] * area) / count
        out[2, n] = (sums[1, b] * area) / w_sum
        out[3, n] = _F(1.0) / w_sum
        # np.rint of a float32 below 2**23 (numba's np.rint of a scalar costs more than
        # the rest): the addition rounds to an integer, half to even.
        out[4, n] = (count + _F(2.0**23)) - _F(2.0**23)
        n += 1
    return out[0, :n], out[1, :n], out[2, :n], out[3, :n], out[4, :n]


def block_points(
    east: np.ndarray,
    north: np.ndarray,
    drop: np.ndarray,
    variance: np.ndarray,
    valid: np.ndarray,
    block: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The valid pixels of each ``block`` x ``block`` square combined into one point.

    Args:
        east, north, drop: (H, W) float32 world coordinates of each pixel's point, m.
        variance: (H, W) float32 variance of each pixel's height, m^2.
        valid: (H, W) bool usable pixels.
        block: block side, pixels.

    Returns:
        x, y, z, variance, count: (B,) float32 per block holding a valid pixel: the mean
        horizontal position, the inverse-variance weighted mean height, the variance
        of that mean (1 / sum of weights) and the number of valid pixels.
    """
    height, width = valid.shape
    rows, cols = height // block, width // block
    # Sums over whole blocks (the few pixels of a partial block at the far edges are left
    # out): the masked images made in one compiled pass, then each averaged over blocks by
    # OpenCV (INTER_AREA averages each block exactly, vectorised), times the block's area.
    planes = np.empty((5, rows * block, cols * block), _F)
    _block_terms(east, north, drop, variance, valid, planes)
    means = np.empty((5, rows, cols), _F)
    for k in range(5):
        cv2.resize(planes[k], (cols, rows), dst=means[k], interpolation=cv2.INTER_AREA)
    return _block_sums_to_points(means, _F(block * block))
