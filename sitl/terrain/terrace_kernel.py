"""The Mars world's terraces (scarps) added to the heights without evaluating ``tanh`` per
cell, yet giving the same heights bit for bit.

A terrace adds ``height * s1 * s2 * s3`` to the float32 grid, each ``s`` a smoothstep
``0.5 (1 + tanh(x))`` of an argument ``x = u / width`` across or along it. numpy's float64
``tanh`` costs ~70 ns per value here and a terrace covers up to 4 million cells: those three
passes were most of a Mars world's generation.

The product matters only through the float32 sum it lands in. Each smoothstep is the
logistic ``1 / (1 + E)``, ``E = exp(-2 x)``, and ``x`` is linear in the cell's offsets
``(dx, dy)``, so ``E`` is a column's factor times a row's factor: the kernel takes ``exp``
once per row and column. Per cell it computes the arguments ``x`` with the same operations
as the array evaluation, corrects the factored ``E`` by the first order of the small
difference between ``-2 x`` and the factored exponent, and brackets
``1 / ((1 + E1) (1 + E2) (1 + E3))`` by ``TOLERANCE`` on either side. It carries both ends
through the float64 product with ``height``, the cast to float32 and the float32 sum; each
step is monotone, so where both ends give the same sum the exact evaluation gives it too,
and the kernel stores it. The cells where they differ (the sum lies that close to a float32
rounding boundary, a few in 10^5) are returned and evaluated exactly as before, with numpy's
``tanh`` (:func:`add_terrace`).

``TOLERANCE`` bounds |exact product - logistic product|. numpy's ``tanh`` errs by a few
units in the last place (<= 5e-16 on each factor in [0, 1]); ``E`` is within
``ulp(|2 x|) + 3 ulp`` of ``exp(-2 x)`` relatively, which moves an unsaturated factor
(|2 x| <= 30) by at most 2e-15 and a saturated one by far less; the products add a few
1e-16: at most ~1e-14 in all, and 1e-12 leaves a margin of a hundred. Terraces whose row or
column exponents exceed ``_SEPARABLE`` (much steeper faces than the settings' defaults)
take ``exp(-2 x)`` per cell instead.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sitl.terrain.features import smoothstep_edge

TOLERANCE = 1e-12
# Largest |exponent| of a row's or a column's factor that the factored form uses.
_SEPARABLE = 300.0
# |x| beyond which the steep face's smoothstep is 0 or 1 to within e^-40 (4e-18, far below
# TOLERANCE): the kernel does not evaluate it there.
_SATURATED = 20.0


@njit(cache=True, inline="always")
def _factor(x, col_exponent, row_exponent, col_factor, row_factor, separable):
    """exp(-2 x): the factored value corrected to first order, or exp itself."""
    if not separable:  # overflow-safe: inf gives a factor 0, the right limit
        return math.exp(-2.0 * x)
    factored = col_factor * row_factor
    return factored + factored * (-2.0 * x - (col_exponent + row_exponent))


@njit(cache=True)
def _add_bracketed(patch, dx, dy, cos, sin, steep, gentle, depth, half_length, height,
                   col_exponent, row_exponent, separable):
    """Add the terrace to ``patch`` where the bracket decides the float32 sum; returns the
    (rows, columns) of the cells it left undecided (unchanged).

    ``col_exponent`` (4, nx) and ``row_exponent`` (4, ny) split ``-2 x`` of the steep face,
    the back edge, and the sides for ``along >= 0`` and ``along < 0``."""
    ny, nx = patch.shape
    rows = np.empty(ny * nx, dtype=np.intp)
    cols = np.empty(ny * nx, dtype=np.intp)
    undecided = 0
    col_factor = np.exp(col_exponent)
    row_factor = np.exp(row_exponent)
    inv_steep = 1.0 / steep
    inv_gentle = 1.0 / gentle
    for i in range(ny):
        # this row's values, held in registers (the stores into patch could alias them)
        sin_dy = sin * dy[i]
        cos_dy = cos * dy[i]
        r0, r1, r2, r3 = row_exponent[0, i], row_exponent[1, i], row_exponent[2, i], \
            row_exponent[3, i]
        f0, f1, f2, f3 = row_factor[0, i], row_factor[1, i], row_factor[2, i], row_factor[3, i]
        for j in range(nx):
            # the arguments of the array evaluation; the products by the reciprocal widths
            # are within an ulp of its quotients, which the tolerance allows
            across = cos * dx[j] + sin_dy
            along = -sin * dx[j] + cos_dy
            x1 = across * inv_steep
            x2 = (depth - across) * inv_gentle
            x3 = (half_length - abs(along)) * inv_gentle
            if x1 < -_SATURATED:  # in front of the face: s1 < e^-40, so h is 0 to 1e-17
                h = 0.0
            else:
                # behind it s1 is 1 to 1e-17: E1 is left out
                e1 = 0.0 if x1 > _SATURATED else _factor(
                    x1, col_exponent[0, j], r0, col_factor[0, j], f0, separable)
                e2 = _factor(x2, col_exponent[1, j], r1, col_factor[1, j], f1, separable)
                if along >= 0.0:
                    e3 = _factor(x3, col_exponent[2, j], r2, col_factor[2, j], f2, separable)
                else:
                    e3 = _factor(x3, col_exponent[3, j], r3, col_factor[3, j], f3, separable)
                h = 1.0 / ((1.0 + e1) * (1.0 + e2) * (1.0 + e3))
            g = patch[i, j]
            low_sum = g + np.float32(height * (h - 2.0 * TOLERANCE))
            high_sum = g + np.float32(height * (h + 2.0 * TOLERANCE))
            # zero sums are left to the exact path: +0 and -0 compare equal
            if low_sum == high_sum and low_sum != 0:
                patch[i, j] = low_sum
            else:
                rows[undecided] = i
                cols[undecided] = j
                undecided += 1
    return rows[:undecided], cols[:undecided]


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
    # -2 x of each smoothstep, split into a column's and a row's part
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
    rows, cols = _add_bracketed(
        patch, dx, dy, float(cos), float(sin), float(steep), float(gentle), float(depth),
        float(half_length), float(height), col_exponent, row_exponent, bool(separable),
    )
    if len(rows):
        patch[rows, cols] += terrace_heights(
            dx[cols], dy[rows], cos, sin, steep, gentle, depth, half_length, height
        )
