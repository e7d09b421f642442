"""The ``mars`` world: fractal relief, craters with raised rims, rock fields whose sizes
follow a power-law size-frequency distribution, and a few steep scarps."""

from __future__ import annotations

import numpy as np

from sitl.terrain.crater_kernel import add_craters
from sitl.terrain.features import (
    fractal_relief,
    poisson_points,
    power_law_sizes,
)
from sitl.terrain.settings import MarsTerrainSettings
from sitl.terrain.stamp_kernels import stamp_ellipses
from sitl.terrain.terrace_kernel import add_terrace
from sitl.terrain.worlds import home_keep_out, procedural_frame

# Crater shape ratios for simple craters (Pike 1977): depth ~ 0.2 D, rim height ~ 0.04 D;
# ejecta thins as (r/R)^-3 out to 3 R.
_DEPTH_RATIO = 0.2
_RIM_RATIO = 0.04
_EJECTA_REACH = 3.0
# Rocks outside rock fields, as a fraction of the in-field density.
_BACKGROUND_ROCKS = 0.03


def generate(
    settings: MarsTerrainSettings, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float]]:
    """(grid, origin) of a Mars-like world."""
    shape, origin = procedural_frame(settings)
    cs = settings.cell_size
    ny, nx = shape
    extent = (origin[0], origin[0] + (nx - 1) * cs, origin[1], origin[1] + (ny - 1) * cs)
    # Steep spectra are smooth at the cell scale: synthesise on ~0.5 m cells then.
    coarsen = max(1, int(0.5 / cs)) if settings.relief_beta >= 3.5 else 1
    grid = fractal_relief(
        shape,
        cs,
        settings.relief_rms,
        settings.relief_wavelength,
        settings.relief_beta,
        rng,
        coarsen=coarsen,
    )
    _add_scarps(grid, origin, cs, extent, settings, rng)
    _add_craters(grid, origin, cs, extent, settings, rng)
    _add_rocks(grid, origin, cs, extent, settings, rng)
    return grid, origin


def _add_craters(grid, origin, cs, extent, settings: MarsTerrainSettings, rng) -> None:
    centers = poisson_points(settings.crater_density * 1e-6, extent, rng)
    dmin, dmax = settings.crater_diameter
    radius = power_law_sizes(len(centers), dmin, dmax, settings.crater_sfd_exponent, rng) / 2
    depth = _DEPTH_RATIO * 2 * radius
    rim = _RIM_RATIO * 2 * radius
    tail = _EJECTA_REACH**-3

    def profile(dx, dy, index):
        R = radius[index, None, None]
        r = np.hypot(dx, dy) / R
        d = depth[index, None, None]
        h_rim = rim[index, None, None]
        bowl = -d + (d + h_rim) * r * r
        ejecta = h_rim * (np.maximum(r, 1.0) ** -3 - tail) / (1.0 - tail)
        h = np.where(r < 1.0, bowl, ejecta)
        return np.where(r <= _EJECTA_REACH, h, np.nan)

    add_craters(grid, origin, cs, centers, radius, depth, rim, tail, _EJECTA_REACH, profile)


def _add_rocks(grid, origin, cs, extent, settings: MarsTerrainSettings, rng) -> None:
    if settings.rock_density == 0:
        return
    # Rock fields: where a smooth random field is in its top `rock_field_fraction`.
    # The field varies over tens of metres: a coarse grid of ~2 m cells is enough.
    coarse = max(1, int(2.0 / cs))
    field = fractal_relief(
        (grid.shape[0] // coarse + 1, grid.shape[1] // coarse + 1),
        cs * coarse,
        1.0,
        60.0,
        4.0,
        rng,
    )
    threshold = np.quantile(field, 1.0 - settings.rock_field_fraction)
    candidates = poisson_points(settings.rock_density, extent, rng)
    col = np.rint((candidates[:, 0] - origin[0]) / (cs * coarse)).astype(np.intp)
    row = np.rint((candidates[:, 1] - origin[1]) / (cs * coarse)).astype(np.intp)
    in_field = field[row, col] >= threshold
    keep = in_field | (rng.random(len(candidates)) < _BACKGROUND_ROCKS)
    keep &= np.hypot(*candidates.T) > home_keep_out(settings) + settings.rock_diameter[1]
    centers = candidates[keep]
    dmin, dmax = settings.rock_diameter
    diameter = power_law_sizes(len(centers), dmin, dmax, settings.rock_sfd_exponent, rng)
    height = settings.rock_height_ratio * diameter * rng.uniform(0.7, 1.3, len(centers))
    # Elliptical footprints with a random orientation: semi-axes a >= b.
    a = diameter / 2
    b = a * rng.uniform(0.6, 1.0, len(centers))
    angle = rng.uniform(0, np.pi, len(centers))
    rocks = np.zeros_like(grid)
    stamp_ellipses(rocks, origin, cs, centers, np.cos(angle), np.sin(angle), a, b, height)
    grid += rocks


def _add_scarps(grid, origin, cs, extent, settings: MarsTerrainSettings, rng) -> None:
    """Raised terraces bounded on one long side by a steep face and gently elsewhere."""
    xmin, xmax, ymin, ymax = extent
    xs = origin[0] + cs * np.arange(grid.shape[1])
    ys = origin[1] + cs * np.arange(grid.shape[0])
    for _ in range(settings.scarp_count):
        height = rng.uniform(*settings.scarp_height)
        slope = np.radians(rng.uniform(*settings.scarp_slope_deg))
        steep = height / (2 * np.tan(slope))
        gentle = height / (2 * np.tan(np.radians(8.0)))
        length = rng.uniform(60.0, 160.0)
        depth = rng.uniform(30.0, 80.0)
        theta = rng.uniform(0, 2 * np.pi)
        # Keep terraces away from home so the clearing stays level.
        for _attempt in range(20):
            cx, cy = rng.uniform(xmin, xmax), rng.uniform(ymin, ymax)
            if np.hypot(cx, cy) > max(length, depth) / 2 + 3 * gentle + 20:
                break
        reach = np.hypot(length / 2, depth) + 3 * gentle
        cols = slice(*np.clip(np.searchsorted(xs, [cx - reach, cx + reach]), 0, len(xs)))
        rows = slice(*np.clip(np.searchsorted(ys, [cy - reach, cy + reach]), 0, len(ys)))
        if cols.start == cols.stop or rows.start == rows.stop:
            continue
        add_terrace(grid[rows, cols], xs[cols], ys[rows], cx, cy, theta, steep, gentle, depth,
                    length, height)
