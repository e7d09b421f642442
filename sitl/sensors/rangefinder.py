"""Downward laser range finder over the terrain."""

from __future__ import annotations

import numpy as np

from sitl.sensors.settings import RangeFinderSettings
from sitl.terrain import Terrain
from sitl.terrain.moving_hits import obstacle_below


class RangeFinder:
    """Measures the distance to the ground along the body -z axis (straight down: the pose
    carries no tilt), with Gaussian noise, within [min_range, max_range].

    Args:
        terrain: the world.
        settings: range limits and noise.
        rng: noise source (``numpy.random.Generator``); default: seeded with 0.
    """

    def __init__(
        self,
        terrain: Terrain,
        settings: RangeFinderSettings | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.terrain = terrain
        self.settings = settings or RangeFinderSettings()
        self.rng = rng if rng is not None else np.random.default_rng(0)

    def true_agl(self, position) -> float:
        """Noise-free height above the ground below ``position`` (ENU m), any sign."""
        x, y, z = (float(v) for v in position)
        at = getattr(self.terrain, "height_at", None)  # a Terrain's scalar lookup is faster
        return z - (at(x, y) if at is not None else float(self.terrain.height(x, y)))

    def measure(self, position, yaw: float = 0.0, time: float | None = None) -> float | None:
        """Measured AGL (m) at ``position`` (3,) ENU, or None when there is no valid
        return: beyond ``max_range``, below ``min_range``, a non-finite pose, or no ground
        below (off an elevation model, or over its nodata cells). With the simulated
        ``time`` (s), a moving obstacle under the sensor returns first."""
        p = np.asarray(position, dtype=np.float64).reshape(-1)
        if p.size != 3 or not np.all(np.isfinite(p)) or not np.isfinite(yaw):
            return None
        if not self.terrain.has_ground(p[0], p[1]):
            return None  # off an elevation model or over its nodata: no return
        agl = self.true_agl(p)
        if time is not None and self.terrain.moving is not None:
            agl = min(agl, obstacle_below(self.terrain.moving, p, time))
        if self.settings.noise_std > 0:
            agl += self.settings.noise_std * float(self.rng.standard_normal())
        if not (self.settings.min_range <= agl <= self.settings.max_range):
            return None
        return agl
