"""Which image tiles of a downward camera can matter to a region of the ground.

A user of the depth image that keeps only the points landing in a box of the ground (an
elevation map's window) needs only the pixels whose measured points can land there, plus
the pixels those depend on (a box filter's reach, blocks of pixels combined into one point).
The camera's tiled ray march already brackets each tile's hits between two ray parameters
``[lo, hi]``; a tile whose rays, anywhere over that bracket widened by the depth noise,
stay outside the box cannot put a point in it, and need not be rendered (see
:class:`GroundRegion` and :func:`tiles_needed`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numba import njit


@dataclass(frozen=True)
class GroundRegion:
    """The ground a depth image's user keeps points from, and what its points depend on.

    Attributes:
        x_min, x_max, y_min, y_max: the ground box, ENU metres.
        reach: pixels (each way) over which a pixel's point depends on its neighbours'
            depths (e.g. a box filter of side ``2 * reach + 1``).
        block: side (px, a power of two up to the caster's tile, or a multiple of it) of
            the aligned pixel blocks the user may combine into one point (1: none).
    """

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    reach: int = 0
    block: int = 1


def tiles_needed(
    region: GroundRegion,
    extents: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    lo: np.ndarray,
    hi: np.ndarray,
    start: tuple[float, float],
    ground: tuple[float, float, float],
    tile: int,
    depth_error: tuple[np.float32, np.ndarray | np.float32] = (np.float32(0.0),
                                                              np.float32(0.0)),
) -> np.ndarray:
    """(rows, cols) bool: the image tiles to render for ``region``.

    Args:
        region: the ground box and its user's pixel dependencies.
        extents: per tile, the extremes (du_min, du_max, dv_min, dv_max) of its rays'
            horizontal components in cells per unit of the ray parameter.
        lo, hi: per tile, the bracket of its rays' hits (ray parameter).
        start: (u, v) of the camera in cell-centre coordinates.
        ground: (origin x, origin y, cell size) of those coordinates.
        tile: tile side, pixels.
        depth_error: (scale, deviates): a pixel's measured depth is ``t + deviate * scale
            * t**2`` for the true one ``t`` (sigma / t**2 = scale), so it lies in ``[t -
            below * t**2, t + above * t**2]`` with ``below = max(-deviate, 0) * scale``
            and ``above = max(deviate, 0) * scale`` (float32 products); ``deviates`` a
            scalar or per pixel (H, W) float32 (the extremes of each tile count).

    A tile is needed when the ground its rays can reach, at any parameter that the
    measured depths of the pixels within ``reach`` can average to (the depths its points
    are placed with), joined with the other tiles of its pixel block, meets the region;
    the pixels within ``reach`` of a needed tile are rendered too (their depths feed its
    points): see :func:`pixels_needed`.
    """
    du_min, du_max, dv_min, dv_max = extents
    x0, y0, cell = ground
    u_o, v_o = start
    box = ((region.x_min - x0) / cell, (region.x_max - x0) / cell,
           (region.y_min - y0) / cell, (region.y_max - y0) / cell)
    # The whole view first: when all the ground it can reach lies in the region, every
    # tile is needed (a low camera).
    scale, deviates = np.float32(depth_error[0]), np.asarray(depth_error[1], np.float32)
    far = float(hi.max())
    far += max(float(_bound(np.max(deviates), scale)), 0.0) * far * far + 0.01 + 1e-4 * far
    if (u_o + min(float(du_min.min()) * far, 0.0) >= box[0]
            and u_o + max(float(du_max.max()) * far, 0.0) <= box[1]
            and v_o + min(float(dv_min.min()) * far, 0.0) >= box[2]
            and v_o + max(float(dv_max.max()) * far, 0.0) <= box[3]):
        return np.ones(lo.shape, dtype=bool)
    below, above = np.empty(lo.shape), np.empty(lo.shape)
    if deviates.ndim == 0:
        below[:], above[:] = _bound(-deviates, scale), _bound(deviates, scale)
    else:
        _tile_bounds(deviates, scale, tile, below, above)
    need = np.empty(lo.shape, dtype=bool)
    _needed(box, (u_o, v_o), -(-max(region.reach, 0) // tile), max(region.block, 1) // tile,
            du_min, du_max, dv_min, dv_max, lo, hi, below, above, need)
    return need


def pixels_needed(region: GroundRegion, need: np.ndarray, tile: int,
                  shape: tuple[int, int]) -> np.ndarray:
    """(H, W) bool pixels to render: those of the needed tiles (from :func:`tiles_needed`)
    and those within ``region.reach`` pixels of them."""
    pixels = np.repeat(np.repeat(need.view(np.uint8), tile, axis=0), tile, axis=1)
    pixels = np.ascontiguousarray(pixels[: shape[0], : shape[1]])
    if region.reach > 0:
        pixels = cv2.dilate(pixels, np.ones((2 * region.reach + 1,) * 2, np.uint8))
    return pixels.view(bool)


def _bound(deviate: np.float32, scale: np.float32) -> np.float32:
    """How far (per unit t**2) a depth with this deviate lies beyond the true one on the
    side where the deviate is positive: ``max(deviate, 0) * scale`` in float32."""
    return max(deviate, np.float32(0.0)) * scale


@njit(cache=True, nogil=True)
def _tile_bounds(deviates, scale, tile, below, above):
    """Per ``tile`` x ``tile`` block of ``deviates`` (tiles cut by the image edge
    included), the largest error below and above of its pixels (float64 of float32
    products): ``max(-lowest, 0) * scale`` and ``max(highest, 0) * scale``, which are the
    largest of the pixels' own (the products round monotonically)."""
    ny, nx = deviates.shape
    zero = np.float32(0.0)
    for i in range(below.shape[0]):
        r0, r1 = i * tile, min((i + 1) * tile, ny)
        for j in range(below.shape[1]):
            c0, c1 = j * tile, min((j + 1) * tile, nx)
            low = high = deviates[r0, c0]
            for r in range(r0, r1):
                for c in range(c0, c1):
                    x = deviates[r, c]
                    low = x if x < low else low
                    high = x if x > high else high
            b = -low
            below[i, j] = (b if b >= zero else zero) * scale
            above[i, j] = (high if high >= zero else zero) * scale


@njit(cache=True, nogil=True)
def _needed(box, start, reach, group, du_min, du_max, dv_min, dv_max, lo, hi, below, above,
            need):
    """The body of :func:`tiles_needed` over its tile arrays, into ``need``."""
    rows, cols = lo.shape
    u_o, v_o = start
    a = np.empty((rows, cols))
    b = np.empty((rows, cols))
    for i in range(rows):
        for j in range(cols):
            h = hi[i, j]
            # Float32 brackets, bilinear heights rounded: a centimetre of slack.
            slack = 0.01 + 1e-4 * h
            square = h * h  # hi >= t: t^2 <= hi^2
            a[i, j] = max(lo[i, j] - below[i, j] * square - slack, 0.0)
            b[i, j] = h + above[i, j] * square + slack
    if reach:  # the placement depth is a mean of the measured depths within reach
        a = _window(a, reach, False)
        b = _window(b, reach, True)
    u0 = np.empty((rows, cols))
    u1 = np.empty((rows, cols))
    v0 = np.empty((rows, cols))
    v1 = np.empty((rows, cols))
    for i in range(rows):
        for j in range(cols):
            ta, tb = a[i, j], b[i, j]
            u0[i, j] = u_o + min(du_min[i, j] * ta, du_min[i, j] * tb)
            u1[i, j] = u_o + max(du_max[i, j] * ta, du_max[i, j] * tb)
            v0[i, j] = v_o + min(dv_min[i, j] * ta, dv_min[i, j] * tb)
            v1[i, j] = v_o + max(dv_max[i, j] * ta, dv_max[i, j] * tb)
    if group > 1:  # a block's point is the mean of its pixels'
        u0, v0 = _blocks(u0, group, False), _blocks(v0, group, False)
        u1, v1 = _blocks(u1, group, True), _blocks(v1, group, True)
    for i in range(rows):
        for j in range(cols):
            need[i, j] = (u1[i, j] >= box[0] and u0[i, j] <= box[1]
                          and v1[i, j] >= box[2] and v0[i, j] <= box[3])


@njit(cache=True, nogil=True)
def _window(a, reach, largest):
    """The smallest (or largest) value over the (2 reach + 1)^2 tiles around each tile
    (edge tiles repeated)."""
    rows, cols = a.shape
    out = a.copy()
    for i in range(rows):
        for j in range(cols):
            for r in range(max(i - reach, 0), min(i + reach + 1, rows)):
                for c in range(max(j - reach, 0), min(j + reach + 1, cols)):
                    out[i, j] = max(out[i, j], a[r, c]) if largest else min(out[i, j], a[r, c])
    return out


@njit(cache=True, nogil=True)
def _blocks(a, group, largest):
    """The smallest (or largest) value of each aligned ``group`` x ``group`` block, spread
    over the block."""
    rows, cols = a.shape
    out = np.empty((rows, cols))
    for i0 in range(0, rows, group):
        for j0 in range(0, cols, group):
            i1, j1 = min(i0 + group, rows), min(j0 + group, cols)
            best = a[i0, j0]
            for r in range(i0, i1):
                for c in range(j0, j1):
                    best = max(best, a[r, c]) if largest else min(best, a[r, c])
            out[i0:i1, j0:j1] = best
    return out
