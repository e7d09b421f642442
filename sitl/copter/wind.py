"""Wind: a constant part plus seeded gusts (first-order Gauss-Markov per horizontal axis)."""

from __future__ import annotations

import math

import numpy as np

from .settings import WindSettings


class Wind:
    """Air velocity over the field, ENU (east, north) m/s. ``advance`` moves the gusts on."""

    def __init__(self, settings: WindSettings, rng: np.random.Generator) -> None:
        self.settings = settings
        self._rng = rng
        # The wind blows FROM ``direction``, so the air moves toward the opposite bearing.
        to = math.radians(settings.direction) + math.pi
        self.steady = (settings.speed * math.sin(to), settings.speed * math.cos(to))
        self.gust = (0.0, 0.0)

    @property
    def velocity(self) -> tuple[float, float]:
        return (self.steady[0] + self.gust[0], self.steady[1] + self.gust[1])

    def advance(self, dt: float) -> tuple[float, float]:
        """Step the gust process by ``dt`` s; returns the new air velocity."""
        s = self.settings
        if s.gust_sigma > 0.0 and dt > 0.0:
            decay = math.exp(-dt / s.gust_time_constant)
            kick = s.gust_sigma * math.sqrt(1.0 - decay * decay)
            n = self._rng.standard_normal(2)
            self.gust = (
                self.gust[0] * decay + kick * float(n[0]),
                self.gust[1] * decay + kick * float(n[1]),
            )
        return self.velocity
