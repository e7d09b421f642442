"""Wind: a constant part plus seeded gusts (first-order Gauss-Markov per horizontal axis)."""

from __future__ import annotations

import math

import numpy as np

from .settings import WindSettings

_BLOCK = 512  # gust normals drawn at once (two per step)


class Wind:
    """Air velocity over the field, ENU (east, north) m/s. ``advance`` moves the gusts on."""

    def __init__(self, settings: WindSettings, rng: np.random.Generator) -> None:
        self.settings = settings
        self._rng = rng
        # The wind blows FROM ``direction``, so the air moves toward the opposite bearing.
        to = math.radians(settings.direction) + math.pi
        self.steady = (settings.speed * math.sin(to), settings.speed * math.cos(to))
        self.gust = (0.0, 0.0)
        # Gust draws come in blocks (the same numbers, in the same order, as one draw of two
        # per step: the generator is the wind's own) and the decay is kept per step length.
        self._normals: list[float] = []
        self._next = 0
        self._dt = math.nan
        self._decay = self._kick = 0.0

    @property
    def velocity(self) -> tuple[float, float]:
        return (self.steady[0] + self.gust[0], self.steady[1] + self.gust[1])

    def advance(self, dt: float) -> tuple[float, float]:
        """Step the gust process by ``dt`` s; returns the new air velocity."""
        s = self.settings
        if s.gust_sigma > 0.0 and dt > 0.0:
            if dt != self._dt:
                self._dt = dt
                self._decay = math.exp(-dt / s.gust_time_constant)
                self._kick = s.gust_sigma * math.sqrt(1.0 - self._decay * self._decay)
            decay, kick = self._decay, self._kick
            i = self._next
            if i >= len(self._normals):
                self._normals = self._rng.standard_normal(_BLOCK).tolist()
                i = 0
            self._next = i + 2
            normals = self._normals
            self.gust = (
                self.gust[0] * decay + kick * normals[i],
                self.gust[1] * decay + kick * normals[i + 1],
            )
        return self.velocity
