"""Ground-truth landing safety of a terrain for a vehicle footprint.

A point is safe when, over the footprint around it,

- the slope of the least-squares plane is at most ``max_slope_deg``;
- the largest |deviation| of the ground from the local plane is at most ``max_rock_height``;
- nothing stands more than ``max_rock_height`` above the local plane within the footprint
  widened by ``clearance_margin`` (rotor clearance).

Footprints are the axis-aligned squares circumscribing the footprint disks (conservative),
so every statistic is a separable box filter: plane fits from box filters of moments
(``scipy.ndimage.uniform_filter`` / ``correlate1d``), deviations from maximum filters. The
"local plane" of a cell is the plane fitted over the footprint centred on that cell; its
value there is the footprint mean, so the deviation field is ``z - mean_footprint(z)``,
exact on planar ground.
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


def _half_cells(length: float, cell_size: float) -> int:
    return max(1, int(np.ceil(length / cell_size - 1e-9)))


def _evaluate(z: np.ndarray, cell_size: float, settings: SafetySettings):
    """Slope (rad), roughness (m) and the obstacle height (m) over the last two axes of
    ``z`` (float64; leading axes are independent patches)."""
    k = _half_cells(settings.footprint_radius, cell_size)
    m = _half_cells(settings.footprint_radius + settings.clearance_margin, cell_size)
    lead = (1,) * (z.ndim - 2)
    size = 2 * k + 1
    mean = ndimage.uniform_filter(z, size=lead + (size, size), mode="nearest")
    # Least-squares plane over a symmetric square: gradient = sum(d * z) / sum(d^2).
    offsets = np.arange(-k, k + 1, dtype=np.float64) * cell_size
    ones = np.ones(size)
    sum_d2 = size * np.sum(offsets**2)
    ax_y, ax_x = z.ndim - 2, z.ndim - 1
    gx = (
        ndimage.correlate1d(
            ndimage.correlate1d(z, ones, axis=ax_y, mode="nearest"),
            offsets,
            axis=ax_x,
            mode="nearest",
        )
        / sum_d2
    )
    gy = (
        ndimage.correlate1d(
            ndimage.correlate1d(z, ones, axis=ax_x, mode="nearest"),
            offsets,
            axis=ax_y,
            mode="nearest",
        )
        / sum_d2
    )
    slope = np.arctan(np.hypot(gx, gy))
    deviation = z - mean
    roughness = ndimage.maximum_filter(np.abs(deviation), size=lead + (size, size), mode="nearest")
    obstacle = ndimage.maximum_filter(deviation, size=lead + (2 * m + 1, 2 * m + 1), mode="nearest")
    return slope, roughness, obstacle


def _mask(slope, roughness, obstacle, settings: SafetySettings) -> np.ndarray:
    return (
        (slope <= np.radians(settings.max_slope_deg))
        & (roughness <= settings.max_rock_height)
        & (obstacle <= settings.max_rock_height)
    )


def _reach_cells(cell_size: float, settings: SafetySettings) -> int:
    # cells whose height influences a point's verdict: the obstacle window plus the
    # footprint around each of its cells (their mean).
    return _half_cells(settings.footprint_radius, cell_size) + _half_cells(
        settings.footprint_radius + settings.clearance_margin, cell_size
    )


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
        slope: (h, w) float32, plane slope in radians.
        roughness: (h, w) float32, largest |deviation| from the plane (m) in the footprint.
    """
    settings = settings or SafetySettings()
    if region is None:
        rows, cols = slice(0, terrain.shape[0]), slice(0, terrain.shape[1])
    else:
        rows, cols = terrain.window(region)
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


def is_safe(terrain: Terrain, x, y, settings: SafetySettings | None = None):
    """Whether landing with the footprint centred at (x, y) is safe (nearest cell).

    ``x`` and ``y`` broadcast; scalars give a bool, arrays a bool ndarray of their shape.
    Each point is evaluated on a small patch of the grid around it (all patches at once).
    Points outside the terrain are unsafe (no ground truth there).
    """
    settings = settings or SafetySettings()
    x, y = np.broadcast_arrays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
    shape = x.shape
    xf, yf = x.reshape(-1), y.reshape(-1)
    finite = np.isfinite(xf) & np.isfinite(yf)
    row, col = terrain.index(np.where(finite, xf, 0.0), np.where(finite, yf, 0.0))
    pad = _reach_cells(terrain.cell_size, settings)
    offsets = np.arange(-pad, pad + 1)
    ny, nx = terrain.shape
    # Clipped indices reproduce the whole-grid filters' "nearest" edge handling.
    rr = np.clip(row[:, None, None] + offsets[None, :, None], 0, ny - 1)
    cc = np.clip(col[:, None, None] + offsets[None, None, :], 0, nx - 1)
    patches = terrain.grid[rr, cc].astype(np.float64)
    slope, roughness, obstacle = (
        a[:, pad, pad] for a in _evaluate(patches, terrain.cell_size, settings)
    )
    safe = _mask(slope, roughness, obstacle, settings)
    safe &= finite & np.asarray(terrain.contains(xf, yf))
    safe = safe.reshape(shape)
    return bool(safe) if safe.ndim == 0 else safe
