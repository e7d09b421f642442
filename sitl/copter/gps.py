"""A scheduled GPS loss and the dead-reckoning drift of the autopilot's position estimate.

Without GPS an EKF integrates its velocity estimate (from an optical-flow sensor, or from
the IMU alone for a few seconds); the error of that velocity makes the position it reports,
and flies position targets by, drift away from the truth. Modelled per axis as a constant
bias, a scale error of the velocity flown and a random walk, drawn from the generator given
(seeded from the mission) and only while GPS is lost, so flights that keep GPS draw nothing.
"""

from __future__ import annotations

import math

import numpy as np

from .settings import GpsLossSettings


class GpsOutage:
    """The GPS state of one flight: lost or not, and the estimate's drift (ENU m).

    Args:
        settings: when GPS is lost and how the estimate drifts.
        rng: the generator of the drift.
    """

    def __init__(self, settings: GpsLossSettings, rng: np.random.Generator) -> None:
        self.settings = settings
        self.rng = rng
        self.lost = False
        self.lost_since: float | None = None
        self.drift = (0.0, 0.0)  # estimate minus truth, ENU m
        self._bias = (0.0, 0.0)
        self._walk = (0.0, 0.0)
        self._scale = 0.0

    def position_failed(self, now: float) -> bool:
        """True once the EKF has no usable horizontal position (no GPS, no velocity aiding,
        for longer than the failsafe delay)."""
        s = self.settings
        return (
            self.lost
            and not s.velocity_aiding
            and self.lost_since is not None
            and now - self.lost_since >= s.failsafe_delay
        )

    def advance(self, now: float, dt: float, velocity: tuple[float, float]) -> str:
        """Advance to ``now`` over a step of ``dt`` s flown at ENU ``velocity`` (m/s);
        returns "lost" or "regained" when the fix changed in this step, else ""."""
        s = self.settings
        if not self.lost:
            end = None if s.duration is None else s.at + s.duration
            if now >= s.at and (end is None or now < end):
                self._lose(now)
                return "lost"
            return ""
        if s.duration is not None and now >= s.at + s.duration:
            self.lost = False
            self.lost_since = None
            self.drift = (0.0, 0.0)
            return "regained"
        walk = self.rng.standard_normal(2) * (s.drift_walk * math.sqrt(dt))
        self._walk = (self._walk[0] + float(walk[0]), self._walk[1] + float(walk[1]))
        ex = self._bias[0] + self._walk[0] + self._scale * velocity[0]
        ey = self._bias[1] + self._walk[1] + self._scale * velocity[1]
        self.drift = (self.drift[0] + ex * dt, self.drift[1] + ey * dt)
        return ""

    def _lose(self, now: float) -> None:
        s = self.settings
        self.lost = True
        self.lost_since = now
        bias = self.rng.standard_normal(2) * s.drift_bias
        self._bias = (float(bias[0]), float(bias[1]))
        self._walk = (0.0, 0.0)
        self._scale = float(self.rng.standard_normal()) * s.drift_scale
        self.drift = (0.0, 0.0)
