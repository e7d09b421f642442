"""Building terrain worlds from their settings: :func:`make_terrain`."""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np

from sitl.terrain.grid import Terrain
from sitl.terrain.settings import TerrainSettings, parse_terrain_settings

# kind -> module with ``generate(settings, rng) -> (grid, origin)``
_GENERATORS = {
    "flat": "sitl.terrain.flat",
    "mars": "sitl.terrain.mars",
    "urban": "sitl.terrain.urban",
    "rubble": "sitl.terrain.rubble",
    "file": "sitl.terrain.files",
}


def make_terrain(settings: TerrainSettings | dict[str, Any], seed: int = 0) -> Terrain:
    """Build the terrain world described by ``settings``, reproducibly from ``seed``.

    The result has home (0, 0) inside it at z = 0, and ground around home flattened over
    ``home_clear_radius`` so that takeoff is safe.

    Args:
        settings: a :data:`TerrainSettings` model, or a mapping to validate into one.
        seed: seed of the ``numpy.random.Generator`` that places every feature.
    """
    settings = parse_terrain_settings(settings)
    rng = np.random.default_rng(seed)
    module = importlib.import_module(generator_module(settings.kind))
    grid, origin, *known = module.generate(settings, rng)  # elevation models: + known mask
    grid = clear_home(grid, origin, settings.cell_size, settings.home_clear_radius)
    known = known[0] if known else None
    terrain = Terrain(grid, settings.cell_size, origin, kind=settings.kind, known=known)
    moving = getattr(settings, "moving_obstacles", None)
    if moving is not None:  # from a stream of their own: the ground above is unchanged
        from sitl.terrain.moving import build_moving, moving_stream

        terrain.moving = build_moving(moving, terrain.extent, home_keep_out(settings),
                                      terrain.height, moving_stream(seed),
                                      streets=settings.kind == "urban")
    return terrain


def generator_module(kind: str) -> str:
    """Name of the module that generates worlds of ``kind`` (imported on first use)."""
    return _GENERATORS[kind]


def procedural_frame(settings) -> tuple[tuple[int, int], tuple[float, float]]:
    """(ny, nx) and origin (x0, y0) of the grid a procedural world's settings describe."""
    nx = int(round(settings.size[0] / settings.cell_size)) + 1
    ny = int(round(settings.size[1] / settings.cell_size)) + 1
    x0 = settings.center[0] - (nx - 1) * settings.cell_size / 2
    y0 = settings.center[1] - (ny - 1) * settings.cell_size / 2
    return (ny, nx), (x0, y0)


def home_keep_out(settings) -> float:
    """Radius (m) around home that generators keep free of features: the takeoff clearing
    plus the ring over which it blends back into the terrain (see :func:`clear_home`)."""
    radius = settings.home_clear_radius
    return 0.0 if radius == 0 else radius + max(radius, 5.0)


def clear_home(
    grid: np.ndarray, origin: tuple[float, float], cell_size: float, radius: float
) -> np.ndarray:
    """Flatten the ground within ``radius`` of home (0, 0) and shift all heights so that
    h(0, 0) = 0. Beyond the radius the level blends back into the terrain over
    ``max(radius, 5 m)`` (a smoothstep), so no cliff is made at the clearing's edge."""
    grid = np.ascontiguousarray(grid, dtype=np.float32)
    # one view of the grid for every lookup below (it sees the in-place changes): each
    # Terrain checks its whole grid when built
    tmp = Terrain(grid, cell_size, origin)
    level = float(tmp.height(0.0, 0.0))
    if radius > 0:
        blend = max(radius, 5.0)
        reach = radius + blend
        rows, cols = tmp.window((-reach, reach, -reach, reach))
        xs, ys = tmp.coordinates()
        d = np.hypot(xs[cols][None, :], ys[rows][:, None])
        # Median height near home: a rock at exactly (0, 0) must not lift the clearing.
        near = d <= radius
        if near.any():
            level = float(np.median(grid[rows, cols][near]))
        s = np.clip((d - radius) / blend, 0.0, 1.0)
        w = 1.0 - s * s * (3.0 - 2.0 * s)
        patch = grid[rows, cols]
        grid[rows, cols] = (w * level + (1.0 - w) * patch).astype(np.float32)
    grid -= np.float32(level)
    # Bilinear h(0, 0) is exactly 0 when the clearing covers the four neighbouring cells;
    # without a clearing subtract the remaining offset too.
    grid -= np.float32(tmp.height(0.0, 0.0))
    return grid
