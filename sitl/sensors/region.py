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
    depth_error: tuple[np.ndarray | float, np.ndarray | float] = (0.0, 0.0),
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
        depth_error: (below, above): a measured depth lies in ``[t - below * t**2,
            t + above * t**2]`` for the true one ``t`` (a noise deviate times sigma / t**2);
            scalars or per-pixel (H, W) arrays (the extremes of each tile count).

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
    far = float(hi.max())
    far += max(float(np.max(depth_error[1])), 0.0) * far * far + 0.01 + 1e-4 * far
    if (u_o + min(float(du_min.min()) * far, 0.0) >= box[0]
            and u_o + max(float(du_max.max()) * far, 0.0) <= box[1]
            and v_o + min(float(dv_min.min()) * far, 0.0) >= box[2]
            and v_o + max(float(dv_max.max()) * far, 0.0) <= box[3]):
        return np.ones(lo.shape, dtype=bool)
    below, above = (_per_tile(e, tile, lo.shape) for e in depth_error)
    # Float32 brackets, fixed-point bilinear heights: a centimetre of slack.
    slack = 0.01 + 1e-4 * hi
    square = np.square(hi)  # hi >= t: t^2 <= hi^2
    a = np.maximum(lo - below * square - slack, 0.0)
    b = hi + above * square + slack
    reach = -(-max(region.reach, 0) // tile)
    if reach:  # the placement depth is a mean of the measured depths within reach
        a = _spread(a, reach, np.minimum)
        b = _spread(b, reach, np.maximum)
    u0 = u_o + np.minimum(du_min * a, du_min * b)
    u1 = u_o + np.maximum(du_max * a, du_max * b)
    v0 = v_o + np.minimum(dv_min * a, dv_min * b)
    v1 = v_o + np.maximum(dv_max * a, dv_max * b)
    group = max(region.block, 1) // tile
    if group > 1:  # a block's point is the mean of its pixels'
        u0, v0 = (_pooled(x, group, np.minimum) for x in (u0, v0))
        u1, v1 = (_pooled(x, group, np.maximum) for x in (u1, v1))
    need = (u1 >= box[0]) & (u0 <= box[1])
    need &= (v1 >= box[2]) & (v0 <= box[3])
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


def _per_tile(error, tile: int, shape: tuple[int, int]):
    """A scalar as it is; per-pixel values as each tile's largest (tiles cut by the image
    edge included)."""
    if np.ndim(error) == 0:
        return float(error)
    return _extremes(np.asarray(error), tile, np.maximum)[: shape[0], : shape[1]].astype(
        np.float64
    )


def _spread(a: np.ndarray, reach: int, pick) -> np.ndarray:
    """``pick`` over the (2 reach + 1)^2 tiles around each tile (edge tiles repeated),
    as a row pass then a column pass of shifted copies (the grids are small)."""
    p = np.pad(a, reach, mode="edge")
    ny, nx = a.shape
    rows = p[:, 0:nx].copy()
    for k in range(1, 2 * reach + 1):
        pick(rows, p[:, k : k + nx], out=rows)
    out = rows[0:ny].copy()
    for k in range(1, 2 * reach + 1):
        pick(out, rows[k : k + ny], out=out)
    return out


def _extremes(a: np.ndarray, group: int, pick) -> np.ndarray:
    """``pick`` over aligned ``group`` x ``group`` blocks of ``a`` (edge-padded)."""
    ny, nx = a.shape
    by, bx = -(-ny // group), -(-nx // group)
    if by * group != ny or bx * group != nx:
        a = np.pad(a, ((0, by * group - ny), (0, bx * group - nx)), mode="edge")
    out = a[0::group, 0::group].copy()
    for i in range(group):
        for j in range(group):
            pick(out, a[i::group, j::group], out=out)
    return out


def _pooled(a: np.ndarray, group: int, pick) -> np.ndarray:
    """``pick`` over aligned ``group`` x ``group`` blocks of ``a``, spread back over them."""
    full = np.repeat(np.repeat(_extremes(a, group, pick), group, axis=0), group, axis=1)
    return full[: a.shape[0], : a.shape[1]]
