"""A depth frame's back-projection for :meth:`ElevationDetector.integrate` as one compiled
pass (numba): the vectorised version made a dozen single-precision passes over the image
(each ray component, each offset, the ray's length along the optical axis, the height
variance); this kernel computes each pixel's in one go, with the same single-precision
operations in the same order, so the points come out bit for bit the same."""

from __future__ import annotations

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

