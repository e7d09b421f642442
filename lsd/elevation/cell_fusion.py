"""The per-cell fusion of :meth:`ElevationMap.fuse_columns` as one compiled pass (numba).

The vectorised version made some thirty numpy passes over the points and the touched cells
(three ``bincount`` sums, a sort of cell-and-height keys, gathers and scatters); this kernel
walks the points twice and the touched cells once, so a frame costs what its points and
cells cost, not what the whole map costs. Every operation is the numpy version's, in the
same precision and order: single-precision cell indices, weights and height levels where the
points are single precision (numpy 2's scalar promotion), double-precision sums taken in
point order (what ``bincount`` does), and the 90th-percentile level as the same order
statistic (the level of the same order statistic of the heights), so the map comes out bit
for bit the same.
"""

from __future__ import annotations

import numpy as np
from numba import njit

TOP_QUANTILE = 0.9  # which percentile of a cell's points is its top
TOP_NOISE_LIFT = 1.2816  # the standard normal's 90th percentile


@njit(cache=True, nogil=True, error_model="numpy")
def _nan_max(a: float, b: float) -> float:
    """``np.maximum`` of two scalars (NaN wins)."""
    if a != a or b != b:
        return a + b
    return a if a >= b else b


@njit(cache=True, nogil=True, error_model="numpy")
def _nan_min(a: float, b: float) -> float:
    """``np.minimum`` of two scalars (NaN wins)."""
    if a != a or b != b:
        return a + b
    return a if a <= b else b


_KEEP = 8  # most values kept by _kth_smallest's network; beyond, a sort


@njit(cache=True, nogil=True, _nrt=False, inline="always")
def _exchange(held: float, v: float) -> tuple[float, float]:
    """One compare-exchange of the network: (the larger, the smaller)."""
    return max(held, v), min(held, v)


@njit(cache=True, nogil=True, error_model="numpy")
def _kth_smallest(values: np.ndarray, a: int, b: int, k: int) -> float:
    """The ``k``-th smallest (0-based) of ``values[a:b]`` (floats, no NaN), which it may
    reorder.

    A cell's top is near the largest of its points: the ``b - a - k`` largest pass through
    a compare-exchange network of two, four or eight places, held in registers and without
    branches on the values (a short sorted list with an insertion per point mispredicted
    its branches on noisy heights), and the smallest of the places that count is the
    answer: the same order statistic as a sort gives."""
    if b - a == 1:
        return values[a]
    keep = b - a - k
    if keep > _KEEP:
        part = values[a:b]
        part.sort()
        return part[k]
    h0 = h1 = h2 = h3 = -np.inf
    if keep <= 2:
        for q in range(a, b):
            h0, v = _exchange(h0, values[q])
            h1 = max(h1, v)
        return h0 if keep == 1 else h1
    if keep <= 4:
        for q in range(a, b):
            h0, v = _exchange(h0, values[q])
            h1, v = _exchange(h1, v)
            h2, v = _exchange(h2, v)
            h3 = max(h3, v)
        return h2 if keep == 3 else h3
    h4 = h5 = h6 = h7 = -np.inf
    for q in range(a, b):
        h0, v = _exchange(h0, values[q])
        h1, v = _exchange(h1, v)
        h2, v = _exchange(h2, v)
        h3, v = _exchange(h3, v)
        h4, v = _exchange(h4, v)
        h5, v = _exchange(h5, v)
        h6, v = _exchange(h6, v)
        h7 = max(h7, v)
    return h4 if keep == 5 else h5 if keep == 6 else h6 if keep == 7 else h7


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _update_cell(cell, w_cell, wz_cell, v_cell, m, percentile, mean, var, top, last_update,
                 closest, now, camera_height, min_var, gate2):
    """One cell's Kalman update from its points' sums and top percentile."""
    meas = wz_cell / w_cell
    point_var = v_cell / m
    meas_top = _nan_max(percentile - TOP_NOISE_LIFT * np.sqrt(point_var), meas)
    meas_var = _nan_max(1.0 / w_cell, min_var)
    mu = mean[cell]
    p = var[cell]  # inf where the cell is new
    old_top = top[cell]
    if not np.isfinite(mu):
        # A new cell starts from its measurement (zero innovation, gain 1 as p is inf).
        mu = meas
        old_top = meas_top
    total = p + meas_var
    innovation = meas - mu
    gain = 1.0 - meas_var / total
    new_var_keep = False
    if innovation * innovation > gate2 * total:
        # The estimate with the smaller variance wins: gain 1 replaces, 0 keeps.
        closer = meas_var < p
        gain = 1.0 if closer else 0.0
        new_var_keep = not closer
    new_mu = mu + gain * innovation
    new_var = p if new_var_keep else gain * meas_var
    new_top = old_top + gain * (meas_top - old_top)
    mean[cell] = new_mu
    top[cell] = _nan_max(new_top, new_mu)
    var[cell] = new_var
    last_update[cell] = now
    if camera_height == camera_height:
        closest[cell] = _nan_min(closest[cell], _nan_max(camera_height - meas, 0.0))


@njit(cache=True, nogil=True, error_model="numpy")
def fuse_cells(
    x, y, z, variance, count,
    inv_rx, origin_i, inv_ry, origin_j, one,
    mean, var, top, last_update, closest,
    n0, n1, now, camera_height, min_var, gate2, point_cell, terms, heights, cell_count,
    cell_list,
):
    """Fuse points into the flattened grids of an (n0, n1) map in place.

    Args:
        x, y, z, variance: (N,) points (float32 or float64; ``z`` and ``variance`` may differ
            in precision from ``x`` and ``y``).
        count: (N,) measurements each point stands for, or an empty array (one each).
        inv_rx, origin_i, inv_ry, origin_j: 1 / resolution and the window's origin cell
            index, in ``x``'s and ``y``'s precision; ``one``: 1.0 in ``variance``'s.
        mean, var, top, last_update, closest: the map's (n0 * n1,) float64 grids.
        now: clock seconds; camera_height: camera ENU z, NaN when unknown.
        min_var: floor of a measurement's variance; gate2: outlier gate squared.
        point_cell: (N or more,) int32, terms: (3, N or more) in the precision of
            ``variance`` and ``z`` combined, heights: (N or more,) of ``z``'s type: work
            space (kept between calls: fresh arrays cost page faults every call; the terms
            in their own precision halve what a single-precision frame moves through the
            cache).
        cell_count: (n0 * n1,) int32 work space, all zero, and left so: the points of each
            cell counted, then where the cell's points go.
        cell_list: (2, n0 * n1) int32 work space: the touched cells of one point and of
            more.

    Returns:
        (number of measurements fused, number of points inside the window).
    """
    n = len(x)
    flat = point_cell
    inside = 0
    lo_cell = np.int64(n0 * n1)
    hi_cell = np.int64(-1)
    z_lo = np.inf
    z_hi = -np.inf
    z_nan = False
    fused = 0.0
    counted = len(count) > 0
    # Each point's cell (-1 outside), then the points of each cell counted: in separate
    # loops, as one loop that both stores a point's cell and counts it in memory runs
    # several times slower (so do the places and the terms below).
    for k in range(n):
        fi = x[k] * inv_rx - origin_i
        fj = y[k] * inv_ry - origin_j
        # NaN fails every comparison and so falls outside.
        if fi >= 0 and fi < n0 and fj >= 0 and fj < n1:
            cell = np.int64(fi) * n1 + np.int64(fj)
            flat[k] = np.int32(cell)
            inside += 1
            if cell < lo_cell:
                lo_cell = cell
            if cell > hi_cell:
                hi_cell = cell
            zk = np.float64(z[k])
            if zk < z_lo:
                z_lo = zk
            if zk > z_hi:
                z_hi = zk
            if zk != zk:
                z_nan = True
            if counted:
                fused += np.float64(count[k])
        else:
            flat[k] = -1
    if inside == 0:
        return 0, 0
    for k in range(n):
        c = flat[k]
        if c >= 0:
            cell_count[c] += 1
    if not counted:  # a sum of ones
        fused = float(inside)
    if z_nan:  # numpy's min and max: NaN
        z_lo = np.nan
        z_hi = np.nan
    span_cells = hi_cell - lo_cell + 1
    # Heights quantised into the low bits of a 62-bit key whose high bits hold the cell
    # (as the vectorised version sorts them): the same number of levels.
    cell_bits = 1
    while (np.int64(1) << cell_bits) < span_cells:  # (span_cells - 1).bit_length(), >= 1
        cell_bits += 1
    height_bits = min(50, 62 - cell_bits)
    top_level = (np.int64(1) << height_bits) - 1
    span = z_hi - z_lo + 1e-9
    quantum = span / float(np.int64(1) << height_bits)
    # The minimum (exact: it is one of z) and 1 / quantum (rounded) in z's precision, as
    # numpy 2 promotes a Python float against z.
    in_z = np.empty(3, z.dtype)
    in_z[0] = z_lo
    in_z[1] = 1.0 / quantum
    low_z, inv_quantum = in_z[0], in_z[1]

    # The points of each cell in their own order (a counting sort), so that sums run in
    # point order as bincount's do: each cell's count becomes where its points start...
    fill = cell_count[lo_cell : hi_cell + 1]
    placed = 0
    for c in range(span_cells):
        m = fill[c]
        fill[c] = placed
        placed += m
    # ...each point's place in cell order replaces its cell (and the starts become ends)...
    for k in range(n):
        c = flat[k]
        if c >= 0:
            c -= lo_cell
            q = fill[c]
            fill[c] = q + 1
            flat[k] = q
    # ...and its terms are written there (so that the cells read them in a row).
    w_of = terms[0]
    wz_of = terms[1]
    v_of = terms[2]
    for k in range(n):
        q = flat[k]
        if q < 0:
            continue
        w = one / variance[k]
        w_of[q] = w
        wz_of[q] = w * z[k]
        v_of[q] = variance[k]
        heights[q] = z[k]

    # The touched cells, those of one point apart (most cells of a frame from 5 m up: a
    # loop without branches on each cell's count), each with where its points end.
    singles = cell_list[0]
    multis = cell_list[1]
    n_single = 0
    n_multi = 0
    b = 0
    for c in range(span_cells):
        a, b = b, fill[c]
        m = b - a
        singles[n_single] = c
        n_single += m == 1
        multis[n_multi] = c
        n_multi += m > 1
    for k in range(n_single):
        c = singles[k]
        q = fill[c] - 1
        level = 0
        if not z_nan:
            in_z[2] = heights[q]
            level = min(np.int64((in_z[2] - low_z) * inv_quantum), top_level)
        # Each sum from zero, as the loop below takes it (-0.0 becomes 0.0).
        _update_cell(c + lo_cell, 0.0 + w_of[q], 0.0 + wz_of[q], 0.0 + v_of[q], 1,
                     z_lo + level * quantum, mean, var, top, last_update, closest, now,
                     camera_height, min_var, gate2)
    for k in range(n_multi):
        c = multis[k]
        a = fill[c - 1] if c > 0 else 0  # where the cell before ends
        b = fill[c]
        # Sums in point order, in double precision, as bincount takes them.
        w_cell = 0.0
        wz_cell = 0.0
        v_cell = 0.0
        for q in range(a, b):
            w_cell += w_of[q]
            wz_cell += wz_of[q]
            v_cell += v_of[q]
        m = b - a
        pick = np.int64(TOP_QUANTILE * (m - 1))
        # The level of the pick-th height: the pick-th level, as a height's level never
        # falls as the height rises (a rounded difference, a rounded positive multiple,
        # truncated). No levels with a NaN height (its cells' heights are NaN anyway).
        level = 0
        if not z_nan:
            in_z[2] = _kth_smallest(heights, a, b, pick)
            level = min(np.int64((in_z[2] - low_z) * inv_quantum), top_level)
        _update_cell(c + lo_cell, w_cell, wz_cell, v_cell, m, z_lo + level * quantum,
                     mean, var, top, last_update, closest, now, camera_height, min_var, gate2)
    fill[:] = 0  # the work space left all zero
    return fused, inside


@njit(cache=True, nogil=True, error_model="numpy")
def forget_cells(mean, top, variance, closest, last_update, cutoff):
    """Forget, in place, the observed cells of the flattened grids last measured before
    ``cutoff``. Returns (how many, the earliest last measurement of the observed cells
    kept: inf when none)."""
    count = 0
    oldest = np.inf
    for c in range(len(mean)):
        if not np.isfinite(mean[c]):
            continue
        t = last_update[c]
        if t < cutoff:
            mean[c] = np.nan
            top[c] = np.nan
            variance[c] = np.inf
            closest[c] = np.inf
            last_update[c] = -np.inf
            count += 1
        elif t < oldest:
            oldest = t
    return count, oldest

