"""The ``rubble`` world: a collapsed-structure field of rough debris piles and scattered
blocks, with a few flat slabs lying among them."""

from __future__ import annotations

import numpy as np

from sitl.terrain.features import fractal_relief, poisson_points, power_law_sizes
from sitl.terrain.settings import RubbleTerrainSettings
from sitl.terrain.stamp_kernels import stamp_boxes_flat, stamp_mounds
from sitl.terrain.worlds import home_keep_out, procedural_frame

# Blocks away from piles, as a fraction of the density near them.
_SCATTERED_BLOCKS = 0.4


def generate(
    settings: RubbleTerrainSettings, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float]]:
    """(grid, origin) of a rubble field."""
    shape, origin = procedural_frame(settings)
    cs = settings.cell_size
    ny, nx = shape
    extent = (origin[0], origin[0] + (nx - 1) * cs, origin[1], origin[1] + (ny - 1) * cs)
    keep_out = home_keep_out(settings)
    grid = fractal_relief(shape, cs, 0.4, 80.0, 4.4, rng, coarsen=max(1, int(1.0 / cs)))

    # Debris piles: rounded mounds ...
    piles = poisson_points(settings.pile_density * 1e-4, extent, rng)
    pile_r = rng.uniform(*settings.pile_radius, len(piles))
    pile_h = rng.uniform(*settings.pile_height, len(piles))
    away = np.hypot(*piles.T) > keep_out + pile_r
    piles, pile_r, pile_h = piles[away], pile_r[away], pile_h[away]

    # (1 - r^2)^2: a rounded mound, flat-topped at its centre, meeting the ground level.
    pile_layer = np.zeros_like(grid)
    stamp_mounds(pile_layer, origin, cs, piles, pile_r, pile_h)
    # ... with a rough surface of broken material.
    texture = fractal_relief(shape, cs, 0.25, 6.0, 2.6, rng)
    grid += pile_layer + texture * np.clip(pile_layer / 0.3, 0.0, 1.0)

    # Blocks: boxes with power-law sizes, denser on and around the piles.
    candidates = poisson_points(settings.block_density, extent, rng)
    col = np.rint((candidates[:, 0] - origin[0]) / cs).astype(np.intp)
    row = np.rint((candidates[:, 1] - origin[1]) / cs).astype(np.intp)
    near_pile = pile_layer[row, col] > 0.05
    keep = near_pile | (rng.random(len(candidates)) < _SCATTERED_BLOCKS)
    keep &= np.hypot(*candidates.T) > keep_out + settings.block_size[1]
    blocks = candidates[keep]
    side = power_law_sizes(len(blocks), *settings.block_size, settings.block_sfd_exponent, rng)
    aspect = rng.uniform(0.4, 1.0, len(blocks))
    block_h = side * rng.uniform(0.3, 0.7, len(blocks))
    angle = rng.uniform(0, np.pi, len(blocks))
    base = grid[row[keep], col[keep]]
    stamp_boxes_flat(grid, origin, cs, blocks, side / np.sqrt(2), np.cos(angle), np.sin(angle),
                     side / 2, aspect * side / 2, base + block_h)

    # Flat slabs: tilted planar rectangles laid over whatever is below them.
    slabs = poisson_points(settings.slab_density * 1e-4, extent, rng)
    xs = origin[0] + cs * np.arange(nx)
    ys = origin[1] + cs * np.arange(ny)
    for cx, cy in slabs:
        size = rng.uniform(*settings.slab_size, 2)
        theta = rng.uniform(0, np.pi)
        tilt = np.tan(np.radians(rng.uniform(0, settings.slab_tilt_deg)))
        tilt_dir = rng.uniform(0, 2 * np.pi)
        raise_by = rng.uniform(0.2, 1.0)
        reach = np.hypot(*size) / 2
        if np.hypot(cx, cy) < keep_out + reach:
            continue
        cols = slice(*np.clip(np.searchsorted(xs, [cx - reach, cx + reach]), 0, nx))
        rows = slice(*np.clip(np.searchsorted(ys, [cy - reach, cy + reach]), 0, ny))
        dx = xs[None, cols] - cx
        dy = ys[rows, None] - cy
        u = np.cos(theta) * dx + np.sin(theta) * dy
        v = -np.sin(theta) * dx + np.cos(theta) * dy
        inside = (np.abs(u) <= size[0] / 2) & (np.abs(v) <= size[1] / 2)
        if not inside.any():
            continue
        patch = grid[rows, cols]
        level = np.median(patch[inside]) + raise_by
        plane = level + tilt * (np.cos(tilt_dir) * dx + np.sin(tilt_dir) * dy)
        grid[rows, cols] = np.where(inside, plane, patch).astype(np.float32)
    return grid, origin
