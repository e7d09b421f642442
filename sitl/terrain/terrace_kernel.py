"""The Mars world's terraces (scarps) added to the heights without evaluating ``tanh`` per
cell, yet giving the same heights bit for bit.

A terrace adds ``height * s1 * s2 * s3`` to the float32 grid, each ``s`` a smoothstep
``0.5 (1 + tanh(u / width))`` of an offset ``u`` across or along it. numpy's float64
``tanh`` costs ~70 ns per value here and a terrace covers up to 4 million cells: those three
passes were most of a Mars world's generation.

The product matters only through the float32 sum it lands in. Each smoothstep is the
logistic ``1 / (1 + exp(-2 u / width))``, and ``u`` is linear in the cell's offsets
``(dx, dy)``, so ``exp(-2 u / width)`` is a column's factor times a row's factor: the kernel
takes ``exp`` once per row and column, and per cell computes
``1 / ((1 + E1) (1 + E2) (1 + E3))``. It brackets that by ``TOLERANCE`` on either side and
carries both ends through the float64 product with ``height``, the cast to float32 and the
float32 sum; each step is monotone, so where both ends give the same sum the exact
evaluation gives it too, and the kernel stores it. The cells where they differ (the sum
lies that close to a float32 rounding boundary, ~1 in 1000) are returned and evaluated
exactly as before, with numpy's ``tanh`` (:func:`add_terrace`).

``TOLERANCE`` bounds |exact product - logistic product|. numpy's ``tanh`` errs by a few
units in the last place (~1e-16 on each factor in [0, 1]); the logistic's exponents are
rounded to within ``_SEPARABLE * 2**-51`` (~1.3e-13), which moves each factor by at most a
quarter of that; the products, sums and ``exp`` add a few 1e-16. 1e-10 leaves a margin of
several hundred. Terraces whose row or column exponents exceed ``_SEPARABLE`` (much steeper
faces than the settings' defaults) take ``exp`` of each cell's exponent instead.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sitl.terrain.features import smoothstep_edge

TOLERANCE = 1e-10
# Largest |exponent| of a row's or a column's factor that the separable form uses.
_SEPARABLE = 300.0


@njit(cache=True)
def _add_bracketed(patch, dx, dy, cos, sin, col_exponent, row_exponent, separable, height):
    """Add the terrace to ``patch`` where the bracket decides the float32 sum; returns a
    uint8 mask of the cells it left undecided (unchanged).

    ``col_exponent`` (4, nx) and ``row_exponent`` (4, ny) split the logistic's exponents of
    the steep face, the back edge, and the sides for ``along >= 0`` and ``along < 0``."""
    ny, nx = patch.shape
    undecided = np.zeros((ny, nx), dtype=np.uint8)
    col_factor = np.exp(col_exponent)
    row_factor = np.exp(row_exponent)
    for i in range(ny):
        for j in range(nx):
            side = 2 if -sin * dx[j] + cos * dy[i] >= 0.0 else 3
            if separable:
                e1 = col_factor[0, j] * row_factor[0, i]
                e2 = col_factor[1, j] * row_factor[1, i]
                e3 = col_factor[side, j] * row_factor[side, i]
            else:  # overflow-safe: exp of the whole exponent (inf -> a factor 0)
                e1 = math.exp(col_exponent[0, j] + row_exponent[0, i])
                e2 = math.exp(col_exponent[1, j] + row_exponent[1, i])
                e3 = math.exp(col_exponent[side, j] + row_exponent[side, i])
            h = 1.0 / ((1.0 + e1) * (1.0 + e2) * (1.0 + e3))
            g = patch[i, j]
            low_sum = g + np.float32(height * (h - 2.0 * TOLERANCE))
            high_sum = g + np.float32(height * (h + 2.0 * TOLERANCE))
            # zero sums are left to the exact path: +0 and -0 compare equal
            if low_sum == high_sum and low_sum != 0:
                patch[i, j] = low_sum
            else:
                undecided[i, j] = 1
    return undecided


def terrace_heights(dx, dy, cos, sin, steep, gentle, depth, half_length, height):
    """Float32 heights a terrace adds at offsets (dx, dy) from its centre: the exact
    evaluation, the definition the bracketed kernel reproduces."""
    across = cos * dx + sin * dy  # 0 at the steep face, +depth at the back edge
    along = -sin * dx + cos * dy
    h = (
        smoothstep_edge(across, steep)
        * smoothstep_edge(depth - across, gentle)
        * smoothstep_edge(half_length - np.abs(along), gentle)
    )
    return (height * h).astype(np.float32)


def add_terrace(patch, xs, ys, cx, cy, theta, steep, gentle, depth, length, height) -> None:
    """Add the terrace centred on (cx, cy) to ``patch`` (float32, rows at ``ys``, columns
    at ``xs``) in place, bit for bit as :func:`terrace_heights` over the whole patch."""
    cos, sin = np.cos(theta), np.sin(theta)
    half_length = length / 2
    dx = xs - cx
    dy = ys - cy
    # -2 u / width of each smoothstep, split into a column's and a row's part
    col_exponent = np.stack([
        -2 * cos * dx / steep,
        2 * cos * dx / gentle,
        -2 * sin * dx / gentle,  # sides, along >= 0: u = half_length - along
        2 * sin * dx / gentle,  # along < 0: u = half_length + along
    ])
    row_exponent = np.stack([
        -2 * sin * dy / steep,
        (2 * sin * dy - 2 * depth) / gentle,
        (2 * cos * dy - 2 * half_length) / gentle,
        (-2 * cos * dy - 2 * half_length) / gentle,
    ])
    separable = max(np.abs(col_exponent).max(), np.abs(row_exponent).max()) <= _SEPARABLE
    undecided = _add_bracketed(patch, dx, dy, float(cos), float(sin), col_exponent,
                               row_exponent, bool(separable), float(height))
    rows, cols = np.nonzero(undecided)
    if len(rows):
        patch[rows, cols] += terrace_heights(
            dx[cols], dy[rows], cos, sin, steep, gentle, depth, half_length, height
        )
