"""Ground-truth landing safety of a terrain for a vehicle footprint.

A point is safe when

- the least-squares plane fitted over the footprint disk (radius ``footprint_radius``) around
  it slopes by at most ``max_slope_deg``;
- the ground deviates by at most ``max_rock_height`` from the local plane anywhere in that
  disk (roughness);
- nothing stands more than ``max_rock_height`` above the local plane anywhere in the
  clearance disk (radius ``footprint_radius + clearance_margin``, rotor clearance).

Disks are sets of grid cells: the cells whose centres lie within the radius of the centre
cell's, i.e. offsets (dx, dy) in cells with dx^2 + dy^2 <= (R / cell_size)^2 (at least the
four neighbours). The "local plane" of a cell is the plane fitted over the footprint disk
centred on that cell. The disk is symmetric, so its gradient is sum(d * z) / sum(d^2) over the
disk and its value at the centre is the disk mean: the deviation field is
``z - mean_footprint(z)``, exact on planar ground.

Disk sums are ``scipy.ndimage.correlate`` with the disk's kernels. A disk is the union of its
rows (row k: |dx| <= w_k = floor(sqrt(R^2 - k^2))), so disk maxima (exact) are maxima of row
maxima, these widened from the row below by the maximum of two shifted views. Every cell's
figures depend only on the heights around it, computed in the same order wherever they are
evaluated, so a window's map equals the whole map there and :func:`is_safe` equals
:func:`safety_map` at cell centres, bit for bit. Edges repeat the nearest cell (like
``mode="nearest"``).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy import ndimage

from sitl.terrain.grid import Terrain


class SafetySettings(BaseModel):
    """Vehicle footprint and the limits of safe ground."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    footprint_radius: float = Field(1.0, gt=0, description="vehicle footprint radius r (m)")
    max_slope_deg: float = Field(15.0, gt=0, lt=90, description="theta_max (deg)")
    max_rock_height: float = Field(
        0.1, gt=0, description="largest deviation from the ground plane (m)"
    )
    clearance_margin: float = Field(
        0.5, ge=0, description="margin beyond the footprint kept free of obstacles (m)"
    )


class _Disk:
    """A disk of grid cells: the offsets (dx, dy) with dx^2 + dy^2 <= (radius / cell)^2.

    Attributes:
        half: h, the largest |offset| in cells (at least 1).
        half_widths: (2h + 1,) int, the half width w_k of row k = -h .. h (|dx| <= w_k).
        mask: (2h + 1, 2h + 1) bool, the disk, row index dy + h, column index dx + h.
    """

    def __init__(self, radius: float, cell_size: float) -> None:
        # A disk smaller than one cell would have no plane to fit: keep the 4 neighbours.
        r2 = max(radius / cell_size, 1.0) ** 2 * (1 + 1e-12)
        self.half = int(np.floor(np.sqrt(r2)))
        rows = np.arange(-self.half, self.half + 1)
        self.half_widths = np.floor(np.sqrt(r2 - rows**2)).astype(int)
        self.mask = np.abs(rows)[None, :] <= self.half_widths[:, None]


def _disk_moments(z: np.ndarray, disk: _Disk, cell_size: float):
    """Mean and least-squares plane gradient (d/dx, d/dy) of ``z`` over the disk around every
    cell of its last two axes (``scipy.ndimage.correlate`` with the disk's kernels)."""
    d = np.arange(-disk.half, disk.half + 1) * cell_size
    ramp_x = np.where(disk.mask, d[None, :], 0.0)
    sum_d2 = np.sum(ramp_x**2)  # the same along y
    lead = (1,) * (z.ndim - 2)
    kernels = (disk.mask / disk.mask.sum(), ramp_x / sum_d2, ramp_x.T / sum_d2)
    return tuple(
        ndimage.correlate(z, k.reshape(lead + k.shape), mode="nearest") for k in kernels
    )


def _disk_max(a: np.ndarray, disk: _Disk) -> np.ndarray:
    """Maximum of ``a`` over the disk around every cell of its last two axes (exact).

    The disk is the union of its rows: the maxima over |dx| <= w along x, for w = 0 .. h,
    each from the previous by the maximum of two shifted views, then the maximum over the
    rows of the disk of the row-wide maxima shifted by the row offset. Same result as
    ``maximum_filter(footprint=disk)`` (tested against it), and faster: every pass is a
    whole-array ``np.maximum`` of two views.
    """
    h, (ny, nx) = disk.half, a.shape[-2:]
    lead = [(0, 0)] * (a.ndim - 2)
    padded = np.pad(a, lead + [(h, h), (h, h)], mode="edge")
    # the row offsets k (cells, -h .. h) of the disk's rows of each half width w
    rows_of_width: dict[int, list[int]] = {}
    for k, w in zip(range(-h, h + 1), disk.half_widths.tolist(), strict=True):
        rows_of_width.setdefault(w, []).append(k)
    out = np.full_like(a, -np.inf)
    # row_max[..., i, j]: maximum of padded[..., i, j .. j + 2w], centred on column j + w
    row_max = padded
    for w in range(h + 1):
        if w == 1:
            row_max = np.maximum(padded[..., :-2], padded[..., 1:-1])
            np.maximum(row_max, padded[..., 2:], out=row_max)
        elif w > 1:
            row_max = np.maximum(row_max[..., :-2], row_max[..., 2:])
        for k in rows_of_width.get(w, ()):
            np.maximum(out, row_max[..., h + k : h + k + ny, h - w : h - w + nx], out=out)
    return out


def _disks(cell_size: float, settings: SafetySettings) -> tuple[_Disk, _Disk]:
    return (
        _Disk(settings.footprint_radius, cell_size),
        _Disk(settings.footprint_radius + settings.clearance_margin, cell_size),
    )


def _evaluate(z: np.ndarray, cell_size: float, settings: SafetySettings):
    """Slope (rad, float64), roughness and obstacle height (m, float32) at every cell of the
    last two axes of ``z`` (float64 heights, m)."""
    footprint, clearance = _disks(cell_size, settings)
    mean, gx, gy = _disk_moments(z, footprint, cell_size)
    slope = np.arctan(np.hypot(gx, gy))
    # float32 deviations: maxima are exact in any precision, and half the memory is faster
    deviation = (z - mean).astype(np.float32)
    roughness = _disk_max(np.abs(deviation), footprint)
    obstacle = _disk_max(deviation, clearance)
    return slope, roughness, obstacle


def _mask(slope, roughness, obstacle, settings: SafetySettings) -> np.ndarray:
    return (
        (slope <= np.radians(settings.max_slope_deg))
        & (roughness <= settings.max_rock_height)
        & (obstacle <= settings.max_rock_height)
    )


def _reach_cells(cell_size: float, settings: SafetySettings) -> int:
    # cells whose height influences a point's verdict: the clearance disk plus the
    # footprint disk around each of its cells (their mean).
    footprint, clearance = _disks(cell_size, settings)
    return footprint.half + clearance.half


def safety_map(
    terrain: Terrain,
    region: tuple[float, float, float, float] | None = None,
    settings: SafetySettings | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Ground-truth safety over the whole grid or a window of it.

    Args:
        terrain: the world.
        region: (xmin, xmax, ymin, ymax) ENU metres; the cells whose centres lie inside
            (see :meth:`Terrain.window`). None: the whole grid.
        settings: footprint and limits.

    Returns:
        mask: (h, w) bool, True where landing is safe.
        slope: (h, w) float32, slope of the footprint's plane in radians.
        roughness: (h, w) float32, largest |deviation| from the plane (m) in the footprint.
    """
    settings = settings or SafetySettings()
    if region is None:
        rows, cols = slice(0, terrain.shape[0]), slice(0, terrain.shape[1])
    else:
        rows, cols = terrain.window(region)
    return _window_map(terrain, rows, cols, settings)


def _window_map(terrain: Terrain, rows: slice, cols: slice, settings: SafetySettings):
    """:func:`safety_map` of the cells ``grid[rows, cols]``."""
    # Evaluate on the window padded by the reach so results equal the whole-grid ones.
    pad = _reach_cells(terrain.cell_size, settings)
    ny, nx = terrain.shape
    r0, r1 = max(0, rows.start - pad), min(ny, rows.stop + pad)
    c0, c1 = max(0, cols.start - pad), min(nx, cols.stop + pad)
    z = terrain.grid[r0:r1, c0:c1].astype(np.float64)
    if z.size == 0:
        empty = np.zeros((rows.stop - rows.start, cols.stop - cols.start))
        return empty.astype(bool), empty.astype(np.float32), empty.astype(np.float32)
    slope, roughness, obstacle = _evaluate(z, terrain.cell_size, settings)
    inner = (
        slice(rows.start - r0, rows.stop - r0),
        slice(cols.start - c0, cols.stop - c0),
    )
    return (
        _mask(slope[inner], roughness[inner], obstacle[inner], settings),
        slope[inner].astype(np.float32),
        roughness[inner].astype(np.float32),
    )


def _safe_centres(terrain: Terrain, row, col, pad: int, settings: SafetySettings):
    """Verdicts at cells (row, col), (n,) each, from a (2 pad + 1)^2 patch around each."""
    offsets = np.arange(-pad, pad + 1)
    ny, nx = terrain.shape
    # Clipped indices reproduce the whole-grid filters' "nearest" edge handling.
    rr = np.clip(row[:, None, None] + offsets[None, :, None], 0, ny - 1)
    cc = np.clip(col[:, None, None] + offsets[None, None, :], 0, nx - 1)
    patches = terrain.grid[rr, cc].astype(np.float64)
    centre = (slice(None), pad, pad)
    return _mask(*(a[centre] for a in _evaluate(patches, terrain.cell_size, settings)), settings)


def is_safe(terrain: Terrain, x, y, settings: SafetySettings | None = None):
    """Whether landing with the footprint centred at (x, y) is safe (nearest cell).

    ``x`` and ``y`` broadcast; scalars give a bool, arrays a bool ndarray of their shape.
    Each point is evaluated on a small patch of the grid around it (all patches at once), or,
    when that is less work, all on one map of the window around them: either way with the
    same verdict as :func:`safety_map` at that cell. Points outside the terrain are unsafe
    (no ground truth there), and so are an elevation model's nodata cells.
    """
    settings = settings or SafetySettings()
    x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    shape = x.shape
    xf, yf = x.reshape(-1), y.reshape(-1)
    finite = np.isfinite(xf) & np.isfinite(yf)
    row, col = terrain.index(np.where(finite, xf, 0.0), np.where(finite, yf, 0.0))
    pad = _reach_cells(terrain.cell_size, settings)
    inside = finite & np.asarray(terrain.contains(xf, yf))
    inside &= terrain.has_ground(np.where(finite, xf, np.nan), np.where(finite, yf, np.nan))
    safe = np.zeros(xf.shape, dtype=bool)
    if inside.any():
        # Many close points: one map over the window around them costs less than a patch
        # each (same arithmetic, same verdicts).
        r0, r1 = row[inside].min(), row[inside].max() + 1
        c0, c1 = col[inside].min(), col[inside].max() + 1
        window_cells = (r1 - r0 + 2 * pad) * (c1 - c0 + 2 * pad)
        if window_cells < inside.sum() * (2 * pad + 1) ** 2:
            mask = _window_map(terrain, slice(r0, r1), slice(c0, c1), settings)[0]
            safe[inside] = mask[row[inside] - r0, col[inside] - c0]
        else:
            safe[inside] = _safe_centres(terrain, row[inside], col[inside], pad, settings)
    safe = safe.reshape(shape)
    return bool(safe) if safe.ndim == 0 else safe
