"""The ``flat`` world: a level plane at z = 0."""

from __future__ import annotations

import numpy as np

from sitl.terrain.settings import FlatTerrainSettings
from sitl.terrain.worlds import procedural_frame


def generate(
    settings: FlatTerrainSettings, rng: np.random.Generator
) -> tuple[np.ndarray, tuple[float, float]]:
    """(grid, origin) of a level plane."""
    shape, origin = procedural_frame(settings)
    return np.zeros(shape, dtype=np.float32), origin
