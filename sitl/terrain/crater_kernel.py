"""The Mars world's craters added to the heights by a compiled kernel, giving the heights the
array profile gives, bit for bit.

A crater adds ``-d + (d + h) r^2`` inside its rim (r < 1, in radii) and the ejecta
``h (r^-3 - 3^-3) / (1 - 3^-3)`` out to three radii, stamped by
:func:`sitl.terrain.features.stamp` with ``np.add.at``: each value is rounded to float32 and
the values are summed into the grid in stamping order. The array profile takes ``np.hypot``
and ``np.power`` per cell (~60 ns). The kernel computes ``r`` with a square root and
``r^-3`` as ``1 / (r r r)``, within ``_RELATIVE`` of the profile's, brackets each value by
what that moves it (``TOLERANCE`` times the value's scale, ``d + h`` in the bowl and
``h r^-3`` on the ejecta) and keeps the
float32 rounding where both ends of the bracket round alike (rounding is monotone, so the
profile's value rounds the same). Cells within the bracket of the rim or of the ejecta's
edge, and values on a float32 rounding boundary (a few in 10^4), are evaluated by the array
profile itself; then every value is added in the stamping order, as ``np.add.at`` did.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from sitl.terrain.features import stamp_boxes

# |kernel r - profile r| <= _RELATIVE r: hypot and sqrt(dx^2 + dy^2) are each within an
# ulp or two of the true distance (2^-52); this allows a thousand times that.
_RELATIVE = 2.0**-40
# |kernel value - profile value| <= TOLERANCE (d + h) in the bowl, TOLERANCE h r^-3 on the
# ejecta: the bowl's slope in r times r is at most 2 (d + h), the ejecta's 3.2 h r^-3, so
# r's error moves a value by at most 3.2 _RELATIVE times that scale; r^-3 (power or
# 1 / r^3) and the other roundings add ~2^-49 of it. TOLERANCE is twice their sum.
TOLERANCE = 2.0**-37

_SKIP, _ADD, _EXACT = 0, 1, 2


@njit(cache=True)
def _evaluate(ny, nx, x0, y0, cs, order, row, col, half, cx, cy, radius, depth, rim, tail,
              reach):
    """Per visited cell in stamping order: flat index, float32 value and what to do
    (_SKIP: outside the crater, _ADD: decided, _EXACT: left to the array profile)."""
    total = 0
    for f in order:
        total += (2 * half[f] + 1) ** 2
    cell = np.empty(total, dtype=np.int64)
    value = np.empty(total, dtype=np.float32)
    status = np.zeros(total, dtype=np.uint8)
    feature = np.empty(total, dtype=np.int64)
    n = 0
    for f in order:
        d, h, big_r = depth[f], rim[f], radius[f]
        bowl_tol = TOLERANCE * (d + h)
        for i in range(row[f] - half[f], row[f] + half[f] + 1):
            if i < 0 or i >= ny:
                continue
            dy = y0 + i * cs - cy[f]
            for j in range(col[f] - half[f], col[f] + half[f] + 1):
                if j < 0 or j >= nx:
                    continue
                dx = x0 + j * cs - cx[f]
                r = math.sqrt(dx * dx + dy * dy) / big_r
                cell[n] = i * nx + j
                feature[n] = f
                margin = 8.0 * _RELATIVE * r
                if r > reach + margin:
                    status[n] = _SKIP
                elif r >= reach - margin or abs(r - 1.0) <= margin:
                    status[n] = _EXACT
                else:
                    if r < 1.0:
                        v = -d + (d + h) * r * r
                        tol = bowl_tol
                    else:
                        inverse_cube = 1.0 / (r * r * r)
                        v = h * (inverse_cube - tail) / (1.0 - tail)
                        tol = TOLERANCE * h * inverse_cube
                    low = np.float32(v - tol)
                    if low == np.float32(v + tol) and low != 0:
                        value[n] = low
                        status[n] = _ADD
                    else:
                        status[n] = _EXACT
                n += 1
    return cell[:n], value[:n], status[:n], feature[:n]


@njit(cache=True)
def _add_in_order(flat, cell, value, status):
    for n in range(len(cell)):
        if status[n] == _ADD:
            flat[cell[n]] += value[n]


def add_craters(layer, origin, cell_size, centers, radius, depth, rim, tail, reach, profile):
    """Add the craters to ``layer`` (float32, in place) as
    ``stamp(layer, origin, cell_size, centers, reach * radius, profile, combine=np.add)``
    does; ``profile`` is that array profile, used where the kernel's bracket is undecided."""
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    if len(centers) == 0:
        return
    ny, nx = layer.shape
    row, col, half, touch = stamp_boxes(layer.shape, origin, cell_size, centers,
                                        reach * radius)
    # stamp's order: by box size, then by feature
    touching = np.flatnonzero(touch)
    order = touching[np.argsort(half[touching], kind="stable")]
    cell, value, status, feature = _evaluate(
        ny, nx, float(origin[0]), float(origin[1]), float(cell_size), order, row, col, half,
        centers[:, 0], centers[:, 1], radius, depth, rim, float(tail), float(reach),
    )
    exact = np.flatnonzero(status == _EXACT)
    if len(exact):
        rows, cols = np.divmod(cell[exact], nx)
        index = feature[exact]
        dx = origin[0] + cols * cell_size - centers[index, 0]
        dy = origin[1] + rows * cell_size - centers[index, 1]
        values = profile(dx[:, None, None], dy[:, None, None], index).reshape(-1)
        finite = np.isfinite(values)
        value[exact] = np.where(finite, values, 0.0).astype(np.float32)
        status[exact] = np.where(finite, _ADD, _SKIP)
    _add_in_order(layer.reshape(-1), cell, value, status)
