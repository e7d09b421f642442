"""From per-cell terrain properties to landing sites: safe mask, size, suppression.

All functions are pure and work on (n, n) grids whose axis 0 is x and axis 1 is y.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING

import cv2
import numpy as np
from numba import njit
from scipy import ndimage

from lsd.distance_transform import distance_at, distance_to_outside, distance_within
from lsd.plane_fit import PlaneFit

if TYPE_CHECKING:  # at run time lsd.elevation imports this module
    from lsd.elevation.settings import DetectorSettings


def maximum_box(array: np.ndarray, size: int) -> np.ndarray:
    """Maximum over the ``size`` x ``size`` square centred on each cell, cells beyond the
    grid ignored (as :func:`scipy.ndimage.maximum_filter` with ``mode="nearest"``, or
    ``"constant"`` with a ``cval`` no larger than any cell), by an OpenCV dilation.

    Args:
        array: (n, m) uint8 or float32 (both run vectorised; float64 is converted to float32).
        size: odd window side, cells.

    Returns:
        (n, m) array of ``array``'s dtype (float32 for float64 input).
    """
    if array.dtype == np.float64:
        array = array.astype(np.float32)
    if size <= 1:
        return array.copy()
    # OpenCV dilates by a rectangle as a row pass then a column pass, in one call (no
    # intermediate image); its default border for dilation is -inf, so cells beyond the
    # grid never win.
    return cv2.dilate(array, _rectangle(size))


@functools.lru_cache(maxsize=8)
def _rectangle(size: int) -> np.ndarray:
    """The ``size`` x ``size`` structuring element of :func:`maximum_box` (read-only)."""
    kernel = cv2.getStructuringElement(cv2.MORPH_RECT, (size, size))
    kernel.flags.writeable = False
    return kernel


def step_hazards(
    fit: PlaneFit, settings: DetectorSettings, resolution: float
) -> tuple[np.ndarray, np.ndarray]:
    """Cells near rocks and holes, each (n, n) bool, both grown by ``clearance_margin``.

    Returns:
        hazard: a cell within ``clearance_margin`` of a cell that sticks out of its own
            footprint plane by more than ``max_step`` plus ``noise_tolerance`` standard
            errors (an unobserved cell has no step: its window's tests stand for it).
        doubtful: a cell within ``clearance_margin`` of a step beyond ``max_step`` that
            only the noise tolerance forgives (the data neither confirm nor rule out a rock).
    """
    level = step_levels(fit, settings, resolution)
    return level >= 2, level >= 1


def step_levels(fit: PlaneFit, settings: DetectorSettings, resolution: float) -> np.ndarray:
    """(n, n) uint8 :func:`step_hazards` in one grid: 2 where ``hazard``, 1 where only
    ``doubtful``, 0 elsewhere."""
    f32 = np.float32
    # One compiled pass; numpy compares float32 grids with Python floats in single
    # precision, and so does it.
    level = _step_levels(fit.step, fit.step_error, f32(settings.max_step),
                         f32(settings.noise_tolerance))
    margin = int(np.ceil(settings.clearance_margin / resolution - 1e-9))
    if margin > 0:  # one maximum filter grows both masks
        level = maximum_box(level, 2 * margin + 1)
    return level


@njit(cache=True, nogil=True, error_model="numpy")
def _step_levels(step, step_error, max_step, k):
    """(n, n) uint8: whether each cell's step exceeds ``max_step`` (NaN does not), plus
    whether it still does less ``k`` standard errors."""
    n0, n1 = step.shape
    level = np.empty((n0, n1), np.uint8)
    for i in range(n0):
        for j in range(n1):
            beyond = step[i, j] > max_step
            level[i, j] = np.uint8(beyond) + np.uint8(step[i, j] - k * step_error[i, j]
                                                      > max_step)
    return level


def step_room(
    fit: PlaneFit,
    settings: DetectorSettings,
    resolution: float,
    wanted: np.ndarray | None = None,
) -> np.ndarray:
    """(n, n) float64 distance in metres from each cell centre to the nearest cell that
    sticks out of its footprint plane by more than ``max_step`` (whether or not the noise
    tolerance forgives it), less half a cell; inf when no cell does (cells beyond the grid
    do not count).

    With ``wanted`` ((n, n) bool), only at those cells and only as far as
    :func:`select_sites` and the doubt test read it (:func:`room_reach`); inf elsewhere
    and beyond: the same sites for far less work, steps being near most cells.
    """
    with np.errstate(invalid="ignore"):
        level = fit.step > settings.max_step  # NaN (unobserved) is no step
    if not level.any():
        return np.full(level.shape, np.inf)
    if wanted is None:
        return site_size(~level, resolution)  # some cell is a step: no border distance
    # Cells beyond `reach` (whole cells, with one to spare) are farther than room_reach.
    reach = int(np.ceil(room_reach(settings, resolution) / resolution + 0.5)) + 1
    return distance_within(~level, wanted, float(resolution), reach)


def step_room_at(
    fit: PlaneFit,
    settings: DetectorSettings,
    resolution: float,
    cell_i: np.ndarray,
    cell_j: np.ndarray,
    bound: np.ndarray,
) -> np.ndarray:
    """(k,) :func:`step_room` at cells (cell_i[k], cell_j[k]) where it is at most
    ``bound[k]`` metres, inf where it is more (each cell searched no farther)."""
    with np.errstate(invalid="ignore"):
        level = fit.step > settings.max_step  # NaN (unobserved) is no step
    if not level.any():
        return np.full(len(cell_i), np.inf)
    # Whole cells, with one to spare: a nearest step beyond them is beyond the bound.
    reaches = np.ceil(np.asarray(bound) / resolution + 0.5).astype(np.int64) + 1
    return distance_at(~level, np.asarray(cell_i, np.int64), np.asarray(cell_j, np.int64),
                       reaches, float(resolution))


def size_cap(settings: DetectorSettings, resolution: float) -> float:
    """Metres beyond which more room does not rank a site higher (see :func:`select_sites`)."""
    block = max(1, int(round(settings.site_spacing / resolution)))
    return settings.footprint_radius + 0.5 * block * resolution


def room_reach(settings: DetectorSettings, resolution: float) -> float:
    """Metres up to which the step room decides anything: the size cap of the ranking, and
    the ring of ``look_margin`` around the footprint that makes a site doubtful."""
    return max(size_cap(settings, resolution), settings.footprint_radius + settings.look_margin)


def safe_mask(fit: PlaneFit, settings: DetectorSettings, hazard: np.ndarray) -> np.ndarray:
    """(n, n) bool: cells that are valid landing area.

    A cell is safe when its footprint window is observed enough, its plane is no steeper
    than ``max_slope`` and no rougher than ``max_roughness``, its heights are certain to
    ``max_uncertainty``, and it is not a step ``hazard`` (from :func:`step_hazards`).
    Slope and roughness limits are widened by ``noise_tolerance`` standard errors of their
    estimates (nothing at close range, much at high altitude). The outermost ring of cells
    is never safe (beyond it the terrain is unknown).
    """
    k = settings.noise_tolerance
    f32 = np.float32
    # One compiled pass for the other limits (numpy compares float32 grids with Python
    # floats in single precision, and so does it); the slope's arctangent (numpy's) only
    # where they pass and the gradient is not so gentle that any arctangent accurate to
    # 0.1 % passes (slope - k * error <= slope for an error >= 0): each cell's test is the
    # same elementwise operations on its own values.
    safe, steep = _safe_but_slope(
        fit.observed_fraction, fit.roughness, fit.roughness_error, fit.sigma, fit.gradient,
        fit.slope_error, np.asarray(hazard, dtype=bool), f32(settings.min_observed_fraction),
        f32(k), f32(settings.max_roughness**2), f32(settings.max_uncertainty),
        f32(np.tan(settings.max_slope_rad) * 0.999),
    )
    if len(steep):
        with np.errstate(invalid="ignore"):
            slope = np.arctan(np.take(fit.gradient, steep))
            slope -= k * np.take(fit.slope_error, steep)
            np.put(safe, steep, slope <= settings.max_slope_rad)
    return safe


@njit(cache=True, nogil=True, error_model="numpy")
def _safe_but_slope(fraction, roughness, roughness_error, sigma, gradient, slope_error,
                    hazard, least_fraction, k, roughest, most_uncertain, gentle):
    """:func:`safe_mask` but for the slope limit of the cells whose gradient is not gentle:
    the mask (the grid's outermost ring never safe) and the flat indices of those cells,
    left False for the caller to test. Each row's tests are taken without branches (as
    bytes, so that they run vectorised), then its steep cells listed."""
    n0, n1 = fraction.shape
    safe = np.zeros((n0, n1), np.uint8)
    steep = np.empty(n0 * n1, np.int64)
    flagged = np.zeros(n1, np.uint8)
    count = 0
    one = np.uint8(1)
    for i in range(1, n0 - 1):
        found = 0
        for j in range(1, n1 - 1):
            r = roughness[i, j]
            rest = (np.uint8(fraction[i, j] >= least_fraction)
                    & np.uint8(r * r - k * roughness_error[i, j] <= roughest)
                    & np.uint8(sigma[i, j] <= most_uncertain) & (np.uint8(hazard[i, j]) ^ one))
            easy = np.uint8(gradient[i, j] <= gentle) & np.uint8(slope_error[i, j] >= 0)
            safe[i, j] = rest & easy
            flagged[j] = rest & (easy ^ one)
            found += flagged[j]
        if found:
            for j in range(1, n1 - 1):
                if flagged[j]:
                    steep[count] = i * n1 + j
                    count += 1
    return safe.view(np.bool_), steep[:count]


def site_size(safe: np.ndarray, resolution: float) -> np.ndarray:
    """(n, n) radius in metres of the largest circle of safe cells centred on each cell.

    One exact Euclidean distance transform of the safe mask
    (:func:`lsd.distance_transform.distance_to_outside`, in whole squared cells, so the same
    on every call and ties between sites break the same way): distance from the cell centre
    to the nearest unsafe cell centre, less half a cell (to that cell's near edge). 0 where
    unsafe. Cells beyond the grid count as unsafe only through the grid's own border cells.
    """
    safe = np.asarray(safe, dtype=bool)
    if safe.all():  # no unsafe cell at all: as scipy's transform, distance to the border
        return np.asarray(ndimage.distance_transform_edt(safe) - 0.5, np.float64) * resolution
    return distance_to_outside(safe, float(resolution))


def obstacle_altitude(
    height: np.ndarray,
    variance: np.ndarray,
    resolution: float,
    radius: float,
    sites: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Highest terrain, ENU z metres, within the square of half-side ``radius``.

    Each observed cell counts with its height plus two sigmas, so that an uncertain map errs
    on the high side; -inf where the square holds no observed cell.

    Args:
        height: (n, m) cell heights, metres; NaN = unobserved.
        variance: (n, m) variance of the heights, m^2.
        resolution: cell side, metres.
        radius: half-side of the square, metres (rounded to whole cells).
        sites: grid indices (i, j), each (k,), of the only cells wanted, or None for all.

    Returns:
        (n, m) grid, or (k,) values at ``sites``.
    """
    half = max(0, int(round(radius / resolution)))
    if sites is None:
        top = np.where(np.isfinite(height), height + 2.0 * np.sqrt(variance), -np.inf)
        return maximum_box(top.astype(np.float32), 2 * half + 1).astype(np.float64)
    i, j = (np.asarray(a, dtype=np.intp) for a in sites)
    if len(i) == 0:
        return np.zeros(0)
    return _highest_around(
        np.asarray(height, dtype=np.float64), np.asarray(variance, dtype=np.float64), i, j, half
    )


@njit(cache=True, nogil=True, error_model="numpy")
def _highest_around(height, variance, i, j, half):
    """(k,) largest ``height + 2 sigma`` (in float32, as the whole-grid version computes
    it) over the square of half-side ``half`` cells around each site, cut at the grid's
    edge; -inf where it holds no observed cell. Only the sites' squares are visited."""
    n0, n1 = height.shape
    i0, i1 = max(i.min() - half, 0), min(i.max() + half + 1, n0)
    j0, j1 = max(j.min() - half, 0), min(j.max() + half + 1, n1)
    top = np.empty((i1 - i0, j1 - j0), np.float32)
    two = np.float32(2.0)
    for a in range(i0, i1):
        for b in range(j0, j1):
            t = np.float32(np.float64(np.sqrt(np.float32(variance[a, b])) * two) + height[a, b])
            top[a - i0, b - j0] = t if t == t else -np.inf  # unobserved (NaN) never wins
    out = np.empty(len(i))
    for k in range(len(i)):
        out[k] = _largest_in(top, max(i[k] - half, 0) - i0, min(i[k] + half + 1, n0) - i0,
                             max(j[k] - half, 0) - j0, min(j[k] + half + 1, n1) - j0)
    return out


@njit(cache=True, nogil=True, error_model="numpy", boundscheck=False)
def _largest_in(top, a0, a1, b0, b1):
    """The largest of ``top[a0:a1, b0:b1]`` (float32, no NaN; -inf if empty): each column's
    largest first, down the rows (vectorised), then across. A maximum of numbers is exact in
    any order, but for the sign of a zero: when the largest is 0, it is taken again in
    row-major order, the first of equals kept, as it always was."""
    best = np.float32(-np.inf)
    if a0 >= a1 or b0 >= b1:
        return best
    column = top[a0, b0:b1].copy()
    for a in range(a0 + 1, a1):
        row = top[a, b0:b1]
        for b in range(b1 - b0):
            column[b] = max(column[b], row[b])
    for v in column:
        best = max(best, v)
    if best == 0:
        best = np.float32(-np.inf)
        for a in range(a0, a1):
            for b in range(b0, b1):
                best = max(best, top[a, b])
    return best


@njit(cache=True, nogil=True, error_model="numpy")
def largest_at(grid, i, j, di, dj):
    """(k,) largest value of ``grid`` (NaN wins, as numpy's max) over the cells
    ``(i[k] + di, j[k] + dj)``, indices clipped to the grid (the nearest edge cell stands for
    cells beyond it)."""
    n0, n1 = grid.shape
    out = np.empty(len(i))
    for k in range(len(i)):
        best = -np.inf
        for m in range(len(di)):
            a = min(max(i[k] + di[m], 0), n0 - 1)
            b = min(max(j[k] + dj[m], 0), n1 - 1)
            v = np.float64(grid[a, b])
            if v != v or best != best:
                best = np.nan
            elif v > best:
                best = v
        out[k] = best
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def cells_at_least(grid, least):
    """The cells where ``grid >= least`` in row-major order: their flat indices, rows and
    columns, each (k,) int64 (``np.flatnonzero`` and ``np.nonzero`` in one go, without a
    mask; numpy's ``nonzero`` of a 2-D mask costs several times the 1-D one)."""
    n0, n1 = grid.shape
    count = 0
    for i in range(n0):
        for j in range(n1):
            count += grid[i, j] >= least
    flat = np.empty(count, np.int64)
    rows = np.empty(count, np.int64)
    cols = np.empty(count, np.int64)
    k = 0
    for i in range(n0):
        for j in range(n1):
            if grid[i, j] >= least:
                flat[k] = i * n1 + j
                rows[k] = i
                cols[k] = j
                k += 1
    return flat, rows, cols


def select_sites(
    size: np.ndarray,
    quality: np.ndarray,
    origin_index: tuple[int, int],
    resolution: float,
    settings: DetectorSettings,
    room: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Non-maximum suppression: at most one site per world-aligned block of the grid.

    Sizes are capped at ``footprint_radius + site_spacing / 2`` (more room than that does not
    make a site better), so that a wide safe area yields a site in every block rather than a
    single one at its centre. In each block of ``site_spacing`` the cell with the largest
    capped size wins, ties broken by ``quality`` and then by nearness to the block centre.
    A winner is then suppressed when another block's winner closer than half a block is
    better (a maximum filter over the winners, done on the grid of blocks), so two sites never
    crowd the border between their blocks. Cells smaller than ``footprint_radius`` are never
    sites. Blocks are aligned to world cell indices so that a site redetected from another
    vehicle position keeps its position.

    Args:
        size: (n, n) site size, metres (from :func:`site_size`).
        quality: (n, n) tie-breaker in [0, 1], larger is better.
        origin_index: world cell index of cell [0, 0].
        resolution: cell side, metres.
        settings: the detector settings.
        room: (n, n) metres or None: a second radius that ranks cells (the smaller of it
            and ``size`` counts) without deciding which cells may be sites, such as the
            distance to the nearest step from :func:`step_room`.

    Returns:
        i, j: grid indices of the sites, each (k,) int64, best first, k <= ``max_sites``.
    """
    i, j = np.nonzero(np.asarray(size) >= settings.footprint_radius)
    if len(i) == 0:
        empty = np.zeros(0, dtype=np.int64)
        return empty, empty
    return rank_sites(i, j, np.asarray(size)[i, j], np.asarray(quality)[i, j], origin_index,
                      resolution, settings, None if room is None else np.asarray(room)[i, j])


def rank_sites(
    i: np.ndarray,
    j: np.ndarray,
    size: np.ndarray,
    quality: np.ndarray,
    origin_index: tuple[int, int],
    resolution: float,
    settings: DetectorSettings,
    room: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`select_sites` given only the cells that may be sites: those at least
    ``footprint_radius`` in size, at grid indices ``i``, ``j`` ((k,) each, in row-major
    order), and their ``size``, ``quality`` and ``room`` ((k,) each), so that the rest of
    the grid need not be looked at, nor their quality worked out."""
    block = max(1, int(round(settings.site_spacing / resolution)))
    cap = size_cap(settings, resolution)
    quality = np.asarray(quality)
    i, j = _block_winners(
        np.asarray(i, np.int64), np.asarray(j, np.int64), np.asarray(size, dtype=np.float64),
        np.zeros(0) if room is None else np.asarray(room, dtype=np.float64),
        quality, quality.dtype.type(1e-3 * resolution), float(cap), 1e-6 * resolution,
        int(origin_index[0]) % block, int(origin_index[1]) % block, block,
    )
    return i[: settings.max_sites], j[: settings.max_sites]


@njit(cache=True, nogil=True, error_model="numpy")
def _block_winners(cell_i, cell_j, size, room, quality, quality_weight, cap, centre_weight,
                   lead0, lead1, block):
    """The sites of :func:`rank_sites`, best first (all of them), in one pass over its
    cells, with its keys computed as the vectorised form of :func:`select_sites` computed
    them (capped size plus ``quality_weight * clip(quality, 0, 1)`` in the quality's
    precision, less ``centre_weight * off_centre / block**2``), the first best cell of a
    block in row-major order (the cells come in that order), and a stable sort."""
    has_room = room.shape[0] > 0
    half_block = (block - 1) / 2
    n0 = cell_i.max() + 1 if len(cell_i) else 0
    n1 = cell_j.max() + 1 if len(cell_j) else 0
    b0 = (n0 + lead0 + block - 1) // block
    b1 = (n1 + lead1 + block - 1) // block
    win_i = np.empty((b0, b1), np.int64)
    win_j = np.empty((b0, b1), np.int64)
    win_key = np.full((b0, b1), -np.inf)
    zero = quality.dtype.type(0.0)
    one = quality.dtype.type(1.0)
    # Blocks and places in them by table (a division per cell costs more than the rest).
    block_j = np.empty(n1, np.int64)
    place_j = np.empty(n1, np.int64)
    for j in range(n1):
        block_j[j], place_j[j] = divmod(j + lead1, block)
    row = -1
    bi, r = 0, 0
    for k in range(len(cell_i)):
        i, j = cell_i[k], cell_j[k]
        if i != row:
            row = i
            bi, r = divmod(i + lead0, block)
        bj, c = block_j[j], place_j[j]
        capped = min(size[k], room[k]) if has_room else size[k]
        capped = min(capped, cap)
        q = min(max(quality[k], zero), one)
        key = capped + np.float64(quality_weight * q)
        key -= centre_weight * (((r - half_block) ** 2 + (c - half_block) ** 2) / (block * block))
        if key > win_key[bi, bj]:
            win_key[bi, bj] = key
            win_i[bi, bj] = i
            win_j[bi, bj] = j
    # A winner closer than half a block (Chebyshev) to a better winner is suppressed; such
    # a neighbour can only sit in one of the 8 adjacent blocks.
    reach = block // 2
    count = 0
    keep_i = np.empty(b0 * b1, np.int64)
    keep_j = np.empty(b0 * b1, np.int64)
    keep_key = np.empty(b0 * b1)
    for bi in range(b0):
        for bj in range(b1):
            key = win_key[bi, bj]
            if not np.isfinite(key):
                continue
            i, j = win_i[bi, bj], win_j[bi, bj]
            beaten = False
            for ni in range(max(bi - 1, 0), min(bi + 2, b0)):
                for nj in range(max(bj - 1, 0), min(bj + 2, b1)):
                    if (ni != bi or nj != bj) and win_key[ni, nj] > key and abs(
                        win_i[ni, nj] - i
                    ) <= reach and abs(win_j[ni, nj] - j) <= reach:
                        beaten = True
            if not beaten:
                keep_i[count] = i
                keep_j[count] = j
                keep_key[count] = key
                count += 1
    order = np.argsort(-keep_key[:count], kind="mergesort")
    return keep_i[:count][order], keep_j[:count][order]
