"""Compiled bilinear upsampling of a coarse relief (:func:`sitl.terrain.features._upsample`):
the same float32 operations as its array version, ``a + w (b - a)`` along the rows and then
along the columns, so the same heights bit for bit (numba compiles without fast-math: no
fused multiply-adds, no reordering), without the full-size temporaries of the array version.
Compiled on first use and cached beside this file."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def upsample_rows_then_columns(coarse, row0, row_weight, col0, col_weight):
    """(len(row0), len(col0)) float32: row ``i`` interpolated between coarse rows
    ``row0[i]`` and ``row0[i] + 1`` with weight ``row_weight[i]``, then each column ``j``
    between columns ``col0[j]`` and ``col0[j] + 1`` of that with ``col_weight[j]``."""
    ny, nx = len(row0), len(col0)
    out = np.empty((ny, nx), dtype=np.float32)
    line = np.empty(coarse.shape[1], dtype=np.float32)
    for i in range(ny):
        w = row_weight[i]
        a = coarse[row0[i]]
        b = coarse[row0[i] + 1]
        for c in range(len(line)):
            line[c] = a[c] + w * (b[c] - a[c])
        for j in range(nx):
            left = line[col0[j]]
            out[i, j] = left + col_weight[j] * (line[col0[j] + 1] - left)
    return out
