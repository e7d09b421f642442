"""Compiled stamps of the features whose heights take only arithmetic and square roots:
Mars rocks (elliptic domes), rubble piles (mounds) and blocks (boxes), each kept where it is
higher than the ground (``np.maximum``). They visit the cells :func:`sitl.terrain.features.
stamp` visits (:func:`~sitl.terrain.features.stamp_boxes`) and compute each height with the
operations of its array profile in the same order, in float64 then rounded to float32, so
the grids are the same bit for bit (numba compiles without fast-math: no fused
multiply-adds, no reordering; a maximum does not depend on the order features come in).
Compiled on first use and cached beside this file."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sitl.terrain.features import stamp_boxes

_ELLIPSE, _MOUND, _BOX = 0, 1, 2


@njit(cache=True, inline="always")
def _height(shape, dx, dy, p):
    """A feature's height at offset (dx, dy) from its centre, NaN where it has none; ``p``
    holds its parameters (see the stamp_* functions)."""
    if shape == _ELLIPSE:  # cos, sin, a, b, height
        u = (p[0] * dx + p[1] * dy) / p[2]
        v = (-p[1] * dx + p[0] * dy) / p[3]
        q = 1.0 - u * u - v * v
        return p[4] * math.sqrt(q) if q > 0 else np.nan
    if shape == _MOUND:  # radius, height
        q = 1.0 - (dx * dx + dy * dy) / (p[0] * p[0])
        return p[1] * q * q if q > 0 else np.nan
    # box: cos, sin, half-length, half-width, top
    inside = abs(p[0] * dx + p[1] * dy) <= p[2] and abs(-p[1] * dx + p[0] * dy) <= p[3]
    return p[4] if inside else np.nan


@njit(cache=True)
def _stamp_max(layer, x0, y0, cs, row, col, half, cx, cy, shape, params):
    ny, nx = layer.shape
    for f in range(len(row)):
        for i in range(max(row[f] - half[f], 0), min(row[f] + half[f] + 1, ny)):
            dy = y0 + i * cs - cy[f]
            for j in range(max(col[f] - half[f], 0), min(col[f] + half[f] + 1, nx)):
                height = _height(shape, x0 + j * cs - cx[f], dy, params[f])
                if not math.isnan(height):
                    value = np.float32(height)
                    if value > layer[i, j]:
                        layer[i, j] = value


def _stamp(layer, origin, cell_size, centers, reach, shape, *params) -> None:
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    row, col, half, touch = stamp_boxes(layer.shape, origin, cell_size, centers, reach)
    k = np.flatnonzero(touch)
    _stamp_max(layer, float(origin[0]), float(origin[1]), float(cell_size), row[k], col[k],
               half[k], centers[k, 0], centers[k, 1], shape,
               np.column_stack([np.asarray(p, dtype=np.float64)[k] for p in params]))


def stamp_ellipses(layer, origin, cell_size, centers, cos, sin, a, b, height) -> None:
    """Elliptic domes ``height sqrt(1 - u^2 - v^2)`` (semi-axes ``a`` >= ``b`` along the
    direction (cos, sin)), kept where higher than ``layer``; all per-feature arrays (n,)."""
    _stamp(layer, origin, cell_size, centers, a, _ELLIPSE, cos, sin, a, b, height)


def stamp_mounds(layer, origin, cell_size, centers, radius, height) -> None:
    """Rounded mounds ``height (1 - r^2 / radius^2)^2``, kept where higher than ``layer``."""
    _stamp(layer, origin, cell_size, centers, radius, _MOUND, radius, height)


def stamp_boxes_flat(layer, origin, cell_size, centers, reach, cos, sin, length, width,
                     top) -> None:
    """Flat-topped boxes at height ``top``: cells within ``length`` along (cos, sin) and
    ``width`` across it (half-extents), kept where higher than ``layer``."""
    _stamp(layer, origin, cell_size, centers, reach, _BOX, cos, sin, length, width, top)
