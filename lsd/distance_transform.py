"""The exact Euclidean distance transform of a grid in whole squared cells (numba).

Meijster, Roerdink and Hesselink's two-pass algorithm ("A general algorithm for computing
distance transforms in linear time", 2000) in integer arithmetic: first each cell's distance
to the nearest outside cell of its column, then, along each row, the lower envelope of the
parabolas those distances span. Squared distances are whole numbers, so they come out exact,
the same on every call: what :func:`cv2.distanceTransform` (precise mask) gives once its
squares are rounded, in one thread (OpenCV's spreads over the cores, which a campaign
already fills with one flight each) and without its float detour.
"""

from __future__ import annotations

import numpy as np
from numba import njit

# Column distances below this fit in int16: half the memory of int32, and twice the lanes
# per vector (the passes are memory and vector bound).
_SHORT = 2**15 - 1


@njit(cache=True, nogil=True, error_model="numpy")
def _column_distances(inside: np.ndarray, far: int) -> np.ndarray:
    """(n0, n1) int32: each cell's distance (in cells) to the nearest outside cell of its
    column, at most ``far``; downwards then upwards, row by row (memory read in order)."""
    n0, n1 = inside.shape
    column = np.empty((n0, n1), np.int32)
    for j in range(n1):
        column[0, j] = far if inside[0, j] else 0
    for i in range(1, n0):
        for j in range(n1):
            column[i, j] = min(column[i - 1, j] + 1, far) if inside[i, j] else 0
    for i in range(n0 - 2, -1, -1):
        for j in range(n1):
            column[i, j] = min(column[i, j], column[i + 1, j] + 1)
    return column


@njit(cache=True, nogil=True, error_model="numpy")
def _short_column_distances(inside: np.ndarray, far: int) -> np.ndarray:
    """:func:`_column_distances` in int16, for ``far`` below ``_SHORT``: the same values,
    each row's update computed in int16 without branches (vectorised)."""
    n0, n1 = inside.shape
    column = np.empty((n0, n1), np.int16)
    flags = inside.view(np.uint8)
    top = np.int16(far)
    one = np.int16(1)
    for j in range(n1):
        column[0, j] = top * np.int16(flags[0, j])
    for i in range(1, n0):
        above, row, flag = column[i - 1], column[i], flags[i]
        for j in range(n1):
            row[j] = min(np.int16(above[j] + one), top) * np.int16(flag[j])
    for i in range(n0 - 2, -1, -1):
        below, row = column[i + 1], column[i]
        for j in range(n1):
            row[j] = min(row[j], np.int16(below[j] + one))
    return column


@njit(cache=True, nogil=True, error_model="numpy")
def distance_to_outside(inside: np.ndarray, resolution: float) -> np.ndarray:
    """(n0, n1) float64 metres from each cell centre to the near edge of the nearest cell
    where ``inside`` is False, never below 0: ``max(sqrt(d2) - 0.5, 0) * resolution`` with
    ``d2`` the squared distance in cells (0 outside) and the root taken in single precision.
    Cells beyond the grid do not count; some cell must be outside.

    Along a row, a run of inside cells between two outside ones needs only its own columns'
    parabolas and those two (any column beyond an outside cell is farther than it), so each
    run gets its own envelope and outside cells none: the same minima, for the inside
    cells' share of the work."""
    n0, n1 = inside.shape
    far = n0 + n1  # farther than any in the grid
    if far < _SHORT:
        return _row_distances(_short_column_distances(inside, far), resolution)
    return _row_distances(_column_distances(inside, far), resolution)


@njit(cache=True, nogil=True, error_model="numpy")
def _row_distances(column: np.ndarray, resolution: float) -> np.ndarray:
    """:func:`distance_to_outside` from the column distances (0 outside)."""
    n0, n1 = column.shape
    out = np.zeros((n0, n1))
    apex = np.empty(n1, np.int64)  # the envelope's parabolas: their apex columns
    first = np.empty(n1, np.int64)  # and the first column where each is the lowest
    height = np.empty(n1, np.int64)  # the row's squared column distances
    for i in range(n0):
        for j in range(n1):
            c = np.int64(column[i, j])
            height[j] = c * c
        u = 0
        while u < n1:
            if height[u] == 0:  # outside: 0 m
                u += 1
                continue
            a = u
            while u < n1 and height[u] > 0:
                u += 1
            # The run a..u-1 and the outside cells bounding it (where the grid has them).
            _run_distances(height, a - 1 if a > 0 else a, u + 1 if u < n1 else u, a, u,
                           apex, first, out[i], resolution)
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _run_distances(height, lo, hi, a, b, apex, first, out_row, resolution):
    """``out_row[a:b]`` from the lower envelope of the parabolas of columns ``lo..hi-1``
    (Meijster's row pass on that stretch)."""
    q = 0
    apex[0] = lo
    first[0] = lo
    for u in range(lo + 1, hi):
        # Drop the parabolas that u's is below from where they begin to be lowest.
        while q >= 0:
            t, s = first[q], apex[q]
            if (t - s) * (t - s) + height[s] <= (t - u) * (t - u) + height[u]:
                break
            q -= 1
        if q < 0:
            q = 0
            apex[0] = u
            first[0] = lo
        else:
            s = apex[q]
            # The first column where u's parabola is below s's (floor division).
            w = 1 + (u * u - s * s + height[u] - height[s]) // (2 * (u - s))
            if w < hi:
                q += 1
                apex[q] = u
                first[q] = w
    for u in range(hi - 1, lo - 1, -1):
        s = apex[q]
        if a <= u < b:
            squared = (u - s) * (u - s) + height[s]
            out_row[u] = max(np.float64(np.sqrt(np.float32(squared))) - 0.5, 0.0) * resolution
        if u == first[q]:
            q -= 1


@njit(cache=True, nogil=True, error_model="numpy")
def distance_within(inside: np.ndarray, wanted: np.ndarray, resolution: float,
                    reach: int) -> np.ndarray:
    """:func:`distance_to_outside` at the ``wanted`` cells only, and only where the nearest
    outside cell is at most ``reach`` cells away (inf elsewhere). Each wanted cell looks
    along its row at the columns' distances, outwards until no nearer cell can be left:
    cheap where outside cells are near, which is where a short reach matters."""
    n0, n1 = inside.shape
    # The columns' distances are only needed up to the reach.
    if reach + 1 < _SHORT:
        return _within_wanted(_short_column_distances(inside, reach + 1), wanted, resolution,
                              reach)
    return _within_wanted(_column_distances(inside, reach + 1), wanted, resolution, reach)


@njit(cache=True, nogil=True, error_model="numpy")
def _within_wanted(column, wanted, resolution, reach):
    """:func:`distance_within` from the column distances (capped at ``reach + 1``)."""
    n0, n1 = column.shape
    out = np.full((n0, n1), np.inf)
    for i in range(n0):
        for u in range(n1):
            if wanted[i, u]:
                out[i, u] = _within(column, i, u, reach, resolution)
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def distance_at(inside: np.ndarray, cell_i: np.ndarray, cell_j: np.ndarray,
                reaches: np.ndarray, resolution: float) -> np.ndarray:
    """(k,) :func:`distance_to_outside` at cells (cell_i[k], cell_j[k]), where the nearest
    outside cell is at most ``reaches[k]`` cells away (inf elsewhere): :func:`distance_within`
    with a reach of each cell's own."""
    far = 0
    for k in range(len(cell_i)):
        far = max(far, reaches[k])
    if far + 1 < _SHORT:
        return _within_at(_short_column_distances(inside, far + 1), cell_i, cell_j, reaches,
                          resolution)
    return _within_at(_column_distances(inside, far + 1), cell_i, cell_j, reaches, resolution)


@njit(cache=True, nogil=True, error_model="numpy")
def _within_at(column, cell_i, cell_j, reaches, resolution):
    """:func:`distance_at` from the column distances (capped beyond every reach)."""
    out = np.empty(len(cell_i))
    for k in range(len(cell_i)):
        out[k] = _within(column, cell_i[k], cell_j[k], reaches[k], resolution)
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _within(column, i, u, reach, resolution):
    """The distance (metres, as :func:`distance_to_outside`) from cell (i, u) to the nearest
    outside cell if that is at most ``reach`` cells away (column distances at least
    ``reach + 1`` where capped), else inf."""
    n1 = column.shape[1]
    limit = reach * reach
    # The exact squared distance if it is at most reach^2: every column within reach is
    # looked at unless a nearer outside cell is already found.
    # (Column distances widened before squaring: they may be int16.)
    c = np.int64(column[i, u])
    best = c * c if c <= reach else limit + 1
    d = 1
    while d * d < best and d <= reach:
        if u - d >= 0:
            c = np.int64(column[i, u - d])
            if c <= reach:
                best = min(best, d * d + c * c)
        if u + d < n1:
            c = np.int64(column[i, u + d])
            if c <= reach:
                best = min(best, d * d + c * c)
        d += 1
    if best > limit:
        return np.inf
    return max(np.float64(np.sqrt(np.float32(best))) - 0.5, 0.0) * resolution
