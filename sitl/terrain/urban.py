"""The ``urban`` world: level ground, a street grid with kerbs, flat-roofed buildings (some
with rooftop units), trees and parked cars."""

from __future__ import annotations

import numpy as np

from sitl.terrain.features import poisson_points, stamp
from sitl.terrain.settings import UrbanTerrainSettings
from sitl.terrain.worlds import home_keep_out, procedural_frame

_KERB = 0.15  # m, pavement above the road
_SETBACK = 1.5  # m, open ground between a building and its lot's edge
_CAR = (4.5, 1.8, 1.5)  # m, length, width, height


def generate(
    settings: UrbanTerrainSettings, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float]]:
    """(grid, origin) of a town."""
    shape, origin = procedural_frame(settings)
    cs = settings.cell_size
    ny, nx = shape
    xs = origin[0] + cs * np.arange(nx)
    ys = origin[1] + cs * np.arange(ny)
    block, road = settings.block_size, settings.road_width
    phase = rng.uniform(0, block, 2)
    # Distance (m) of each column / row to the nearest road centreline.
    road_x = np.abs((xs - phase[0] + block / 2) % block - block / 2)
    road_y = np.abs((ys - phase[1] + block / 2) % block - block / 2)
    on_road = (road_y[:, None] <= road / 2) | (road_x[None, :] <= road / 2)
    grid = np.where(on_road, 0.0, _KERB).astype(np.float32)
    extent = (xs[0], xs[-1], ys[0], ys[-1])

    def cell_slice(lo: float, hi: float, axis: np.ndarray) -> slice:
        return slice(*np.clip(np.searchsorted(axis, [lo, hi]), 0, len(axis)))

    # Buildings: each block's interior is split into lots; a lot is built over with the
    # probability that gives the requested built-over fraction.
    inner = block - road
    mean_side = float(np.mean(settings.building_size))
    fraction = max(settings.building_fraction, 1e-3)
    lots = max(1, int(round(inner * np.sqrt(fraction) / mean_side)))
    lot = inner / lots
    room = max(lot - 2 * _SETBACK, 1.0)
    lo_side = min(settings.building_size[0], room)
    hi_side = min(settings.building_size[1], room)
    p_build = min(1.0, settings.building_fraction * lot * lot / ((lo_side + hi_side) / 2) ** 2)
    bx0 = np.arange(np.floor((extent[0] - phase[0]) / block) - 1, (extent[1] - phase[0]) / block)
    by0 = np.arange(np.floor((extent[2] - phase[1]) / block) - 1, (extent[3] - phase[1]) / block)
    lot_idx = np.arange(lots)
    lx = (phase[0] + bx0[:, None] * block + road / 2 + lot_idx[None, :] * lot).ravel()
    ly = (phase[1] + by0[:, None] * block + road / 2 + lot_idx[None, :] * lot).ravel()
    LX, LY = np.meshgrid(lx, ly)
    LX, LY = LX.ravel(), LY.ravel()
    built = rng.random(LX.size) < p_build
    w = rng.uniform(lo_side, hi_side, LX.size)
    d = rng.uniform(lo_side, hi_side, LX.size)
    height = rng.uniform(*settings.building_height, LX.size)
    ox = rng.uniform(0, 1, LX.size) * (room - w) + _SETBACK
    oy = rng.uniform(0, 1, LX.size) * (room - d) + _SETBACK
    unit = rng.random(LX.size) < settings.rooftop_clutter
    unit_size = rng.uniform(1.5, 4.0, LX.size)
    unit_height = rng.uniform(1.0, 2.5, LX.size)
    ux = rng.uniform(0, 1, LX.size)
    uy = rng.uniform(0, 1, LX.size)
    keep_out = home_keep_out(settings)
    # Nothing is built over home's clearing: distance from home to each rectangle.
    bx, by = LX + ox, LY + oy
    gap = np.hypot(
        np.maximum.reduce([bx, -(bx + w), np.zeros_like(bx)]),
        np.maximum.reduce([by, -(by + d), np.zeros_like(by)]),
    )
    built &= gap > keep_out
    for k in np.flatnonzero(built):
        x0, y0 = bx[k], by[k]
        rows = cell_slice(y0, y0 + d[k], ys)
        cols = cell_slice(x0, x0 + w[k], xs)
        grid[rows, cols] = _KERB + height[k]
        if unit[k]:
            s = min(unit_size[k], w[k] / 2, d[k] / 2)
            cx = x0 + s / 2 + ux[k] * (w[k] - s) - s / 2
            cy = y0 + s / 2 + uy[k] * (d[k] - s) - s / 2
            rows = cell_slice(cy, cy + s, ys)
            cols = cell_slice(cx, cx + s, xs)
            grid[rows, cols] = _KERB + height[k] + unit_height[k]

    # Trees on open ground (pavement level, not roads, not buildings).
    candidates = poisson_points(settings.tree_density * 1e-4, extent, rng)
    col = np.clip(np.rint((candidates[:, 0] - origin[0]) / cs).astype(np.intp), 0, nx - 1)
    row = np.clip(np.rint((candidates[:, 1] - origin[1]) / cs).astype(np.intp), 0, ny - 1)
    trees = candidates[
        (grid[row, col] == np.float32(_KERB)) & (np.hypot(*candidates.T) > keep_out + 6.0)
    ]
    tree_h = rng.uniform(*settings.tree_height, len(trees))
    crown = tree_h * rng.uniform(0.25, 0.4, len(trees))

    def canopy(dx, dy, index):
        r = np.hypot(dx, dy) / crown[index, None, None]
        # A rounded crown: full height at the trunk, dropping to 60 % at the crown's edge.
        return np.where(r <= 1.0, _KERB + tree_h[index, None, None] * (1.0 - 0.4 * r * r), np.nan)

    stamp(grid, origin, cs, trees, crown, canopy, combine=np.maximum)

    # Parked cars along the kerbs: on roads, against their edge, aligned with the road.
    length, width, car_h = _CAR
    n_cars = rng.poisson(
        settings.car_density / 100.0 * (extent[1] - extent[0]) * 2 * (extent[3] - extent[2]) / block
    )
    along = rng.uniform(0, 1, n_cars)
    horizontal = rng.random(n_cars) < 0.5
    line = rng.integers(0, max(1, int((extent[3] - extent[2]) / block) + 2), n_cars)
    side = np.where(rng.random(n_cars) < 0.5, -1.0, 1.0)
    offset = side * (road / 2 - width / 2 - 0.3)
    for k in range(n_cars):
        if horizontal[k]:
            cx = extent[0] + along[k] * (extent[1] - extent[0])
            cy = phase[1] + (line[k] + by0[0]) * block + offset[k]
            half = (length / 2, width / 2)
        else:
            cx = phase[0] + (line[k] + bx0[0]) * block + offset[k]
            cy = extent[2] + along[k] * (extent[3] - extent[2])
            half = (width / 2, length / 2)
        if np.hypot(cx, cy) < keep_out + length:
            continue
        rows = cell_slice(cy - half[1], cy + half[1], ys)
        cols = cell_slice(cx - half[0], cx + half[0], xs)
        grid[rows, cols] = np.maximum(grid[rows, cols], car_h)
    return grid, origin
