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


@njit(cache=True)
def _ellipses(layer, x0, y0, cs, row, col, half, cx, cy, cos, sin, a, b, height):
    ny, nx = layer.shape
    for f in range(len(row)):
        c, s = cos[f], sin[f]
        for i in range(max(row[f] - half[f], 0), min(row[f] + half[f] + 1, ny)):
            dy = y0 + i * cs - cy[f]
            for j in range(max(col[f] - half[f], 0), min(col[f] + half[f] + 1, nx)):
                dx = x0 + j * cs - cx[f]
                u = (c * dx + s * dy) / a[f]
                v = (-s * dx + c * dy) / b[f]
                q = 1.0 - u * u - v * v
                if q > 0:
                    value = np.float32(height[f] * math.sqrt(q))
                    if value > layer[i, j]:
                        layer[i, j] = value


@njit(cache=True)
def _mounds(layer, x0, y0, cs, row, col, half, cx, cy, radius, height):
    ny, nx = layer.shape
    for f in range(len(row)):
        r2 = radius[f] * radius[f]
        for i in range(max(row[f] - half[f], 0), min(row[f] + half[f] + 1, ny)):
            dy = y0 + i * cs - cy[f]
            for j in range(max(col[f] - half[f], 0), min(col[f] + half[f] + 1, nx)):
                dx = x0 + j * cs - cx[f]
                q = 1.0 - (dx * dx + dy * dy) / r2
                if q > 0:
                    value = np.float32(height[f] * q * q)
                    if value > layer[i, j]:
                        layer[i, j] = value


@njit(cache=True)
def _boxes(layer, x0, y0, cs, row, col, half, cx, cy, cos, sin, length, width, top):
    ny, nx = layer.shape
    for f in range(len(row)):
        c, s = cos[f], sin[f]
        for i in range(max(row[f] - half[f], 0), min(row[f] + half[f] + 1, ny)):
            dy = y0 + i * cs - cy[f]
            for j in range(max(col[f] - half[f], 0), min(col[f] + half[f] + 1, nx)):
                dx = x0 + j * cs - cx[f]
                if abs(c * dx + s * dy) <= length[f] and abs(-s * dx + c * dy) <= width[f]:
                    value = np.float32(top[f])
                    if value > layer[i, j]:
                        layer[i, j] = value


def _touching(layer, origin, cell_size, centers, reach):
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    row, col, half, touch = stamp_boxes(layer.shape, origin, cell_size, centers, reach)
    keep = np.flatnonzero(touch)
    return (float(origin[0]), float(origin[1]), float(cell_size), row[keep], col[keep],
            half[keep], centers[keep, 0], centers[keep, 1]), keep


def stamp_ellipses(layer, origin, cell_size, centers, cos, sin, a, b, height) -> None:
    """Elliptic domes ``height sqrt(1 - u^2 - v^2)`` (semi-axes ``a`` >= ``b`` along the
    direction (cos, sin)), kept where higher than ``layer``; all per-feature arrays (n,)."""
    frame, k = _touching(layer, origin, cell_size, centers, a)
    _ellipses(layer, *frame, cos[k], sin[k], a[k], b[k], height[k])


def stamp_mounds(layer, origin, cell_size, centers, radius, height) -> None:
    """Rounded mounds ``height (1 - r^2 / radius^2)^2``, kept where higher than ``layer``."""
    frame, k = _touching(layer, origin, cell_size, centers, radius)
    _mounds(layer, *frame, radius[k], height[k])


def stamp_boxes_flat(layer, origin, cell_size, centers, reach, cos, sin, length, width,
                     top) -> None:
    """Flat-topped boxes at height ``top``: cells within ``length`` along (cos, sin) and
    ``width`` across it (half-extents), kept where higher than ``layer``."""
    frame, k = _touching(layer, origin, cell_size, centers, reach)
    _boxes(layer, *frame, cos[k], sin[k], length[k], width[k], top[k])
