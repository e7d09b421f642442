"""Gusts are the seeded first-order Gauss-Markov process, whatever the step lengths: each
step draws the next two standard normals of the wind's own generator."""

from __future__ import annotations

import math

import numpy as np

from sitl.copter.settings import WindSettings
from sitl.copter.wind import Wind


def test_gusts_follow_the_seeded_process_step_by_step():
    settings = WindSettings(speed=3.0, direction=250.0, gust_sigma=0.5, gust_time_constant=3.0)
    wind = Wind(settings, np.random.default_rng(42))
    reference = np.random.default_rng(42)
    gust = (0.0, 0.0)
    steps = np.random.default_rng(1).choice([0.05, 0.1, 0.25, 0.0], size=3000)
    for dt in steps:
        got = wind.advance(float(dt))
        if dt > 0:
            decay = math.exp(-dt / settings.gust_time_constant)
            kick = settings.gust_sigma * math.sqrt(1.0 - decay * decay)
            n = reference.standard_normal(2)
            gust = (gust[0] * decay + kick * float(n[0]), gust[1] * decay + kick * float(n[1]))
        assert got == (wind.steady[0] + gust[0], wind.steady[1] + gust[1])
