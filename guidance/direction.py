"""Guiding direction estimator: a bearing particle filter (Lee et al., Sensors 2019, Algorithm 1).

A ring of light sensors reports the bearing a ground laser comes from; that measurement is
quantised (30 deg sensors), widened by neighbouring sensors at range and polluted by
momentary reflections. The filter keeps N_s bearing particles (the state l = [cos, sin,
theta] of the paper with radius 1, so only theta is stored) and, for each measurement:

1. draws every particle from the transitional prior theta_k = theta_{k-1} + v_k,
   v_k ~ N(0, process_noise^2) (the operator keeps the laser on the vehicle, so the
   bearing changes slowly);
2. multiplies its weight by the likelihood p(z_k | theta_k), a wrapped Gaussian of the
   angular difference with the measurement noise, mixed with a uniform density for
   reflections (computed in logarithms so a measurement far from every particle never
   underflows to 0/0);
3. normalises the weights;
4. if the effective sample size N_eff = 1 / sum w^2 falls below N_T (default N_s / 2),
   resamples systematically, sets every weight to 1 / N_s, and disperses a fraction
   (default 10 %) of the particles uniformly over the whole circle, so that a sudden change
   of the light's direction is picked up without waiting for the process noise to walk
   there (sample impoverishment, section 3.2.2);
5. estimates the bearing as the weighted mean S_k = sum w l of the particle states, i.e.
   the direction of the weighted mean of the unit vectors (a plain mean of angles would
   break at +-pi), taken over the particles around the direction holding the most weight
   ("the UAV can fly to the direction of the most particles", section 3.2.1), so that the
   few dispersed particles a reflection favours cannot pull the estimate sideways.

Bearings are in radians, in whatever frame the caller measures them (the project uses
ENU: 0 = east, counter-clockwise). All randomness comes from the numpy Generator given to
the constructor. Every step is vectorised over the particles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * math.pi
_MODE_BINS = 72  # 5 deg histogram bins for the direction of the most particles
_MODE_SMOOTHING = 3  # +-3 bins (15 deg), half a light sensor
_MODE_HALF_WIDTH = math.radians(45.0)
_TINY = 1e-300  # floor before a logarithm: a weight of exactly 0 would stay 0 forever


@dataclass(frozen=True)
class DirectionEstimatorSettings:
    """Parameters of the guiding direction estimator (defaults from the paper, section 5.2).

    n_particles: N_s, 500 in the paper (table 1: RMSE under 1 deg from 500 up).
    resample_threshold: N_T; None means N_s / 2 (250 at 500 particles, as in the paper).
    process_noise: standard deviation (rad) of the bearing's random walk per update.
    measurement_noise: standard deviation (rad) of the measured bearing; a 30 deg sensor
        that returns its middle value has a uniform error of +-15 deg, whose standard
        deviation is 30 deg / sqrt(12) ~ 8.7 deg; the default adds a little for reflections.
    dispersion_fraction: share of the particles spread uniformly over the circle after each
        resampling (10 % in the paper); 0 turns dispersion off (a plain SIR filter).
    outlier_probability: chance that a reading is a momentary reflection from anywhere
        (section 4.1.1); the likelihood is a mixture of the wrapped Gaussian and a uniform
        density, so one reflection cannot hand all the weight to the few dispersed
        particles that happen to lie in its direction.
    """

    n_particles: int = 500
    resample_threshold: float | None = None
    process_noise: float = math.radians(2.0)
    measurement_noise: float = math.radians(10.0)
    dispersion_fraction: float = 0.10
    outlier_probability: float = 0.2

    def __post_init__(self) -> None:
        if not isinstance(self.n_particles, int) or self.n_particles < 2:
            raise ValueError(f"n_particles must be an integer >= 2, got {self.n_particles!r}")
        for name in ("process_noise", "measurement_noise"):
            value = getattr(self, name)
            if not math.isfinite(value) or value <= 0:
                raise ValueError(f"{name} must be a finite angle > 0 rad, got {value!r}")
        if not 0.0 <= self.dispersion_fraction < 1.0 or math.isnan(self.dispersion_fraction):
            raise ValueError(
                f"dispersion_fraction must be in [0, 1), got {self.dispersion_fraction!r}"
            )
        if not 0.0 <= self.outlier_probability < 1.0 or math.isnan(self.outlier_probability):
            raise ValueError(
                f"outlier_probability must be in [0, 1), got {self.outlier_probability!r}"
            )
        threshold = self.resample_threshold
        if threshold is not None and not 0.0 < threshold <= self.n_particles:
            raise ValueError(
                f"resample_threshold must be in (0, n_particles={self.n_particles}], "
                f"got {threshold!r}"
            )

    @property
    def threshold(self) -> float:
        """N_T as used: the setting, or N_s / 2."""
        if self.resample_threshold is None:
            return self.n_particles / 2.0
        return float(self.resample_threshold)


def wrap_angle(angle: np.ndarray | float) -> np.ndarray | float:
    """Wrap angles to [-pi, pi)."""
    return (np.asarray(angle) + math.pi) % TWO_PI - math.pi


def systematic_resample(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Indices drawn by systematic resampling: one uniform offset, N evenly spaced pointers.

    O(N) and with the lowest variance of the classic schemes (Arulampalam et al. 2002).
    """
    n = weights.size
    positions = (rng.random() + np.arange(n)) / n
    cumulative = np.cumsum(weights)
    cumulative[-1] = 1.0  # guard against rounding leaving the last pointer past the end
    return np.searchsorted(cumulative, positions, side="right")


class GuidingDirectionEstimator:
    """Bearing particle filter with systematic resampling and sample dispersion.

    Call update(z) for every laser measurement (a bearing in radians) and read `bearing`;
    update(None) (no laser this cycle) leaves the filter untouched, as Algorithm 1 runs only
    while a measurement arrives. `bearing` is None until the first measurement.
    """

    def __init__(
        self,
        settings: DirectionEstimatorSettings | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.settings = settings or DirectionEstimatorSettings()
        if rng is None:
            raise ValueError("a numpy Generator is required (seed it from the mission)")
        self._rng = rng
        self.reset()

    def reset(self) -> None:
        """Initialisation of Algorithm 1: particles evenly over the circle, equal weights."""
        n = self.settings.n_particles
        self.particles = np.linspace(-math.pi, math.pi, n, endpoint=False)
        self.weights = np.full(n, 1.0 / n)
        self.updates = 0
        self.resamplings = 0
        self._bearing: float | None = None

    @property
    def bearing(self) -> float | None:
        """Estimated bearing (rad, [-pi, pi)), None before any measurement."""
        return self._bearing

    @property
    def effective_sample_size(self) -> float:
        """N_eff = 1 / sum w^2 of the current weights."""
        return float(1.0 / np.dot(self.weights, self.weights))

    @property
    def concentration(self) -> float:
        """Length of the weighted mean unit vector: 1 when all particles agree, ~0 when spread.

        A caller uses it to refuse to fly a bearing the filter has no evidence for.
        """
        c = float(np.dot(self.weights, np.cos(self.particles)))
        s = float(np.dot(self.weights, np.sin(self.particles)))
        return math.hypot(c, s)

    def update(self, measured_bearing: float | None) -> float | None:
        """One step of Algorithm 1 for a measured bearing; returns the estimate."""
        if measured_bearing is None:
            return self._bearing
        z = float(measured_bearing)
        if not math.isfinite(z):
            # A broken reading is no evidence: keep the filter as it is.
            return self._bearing
        cfg = self.settings
        rng = self._rng
        n = cfg.n_particles
        # Transitional prior (proposal): theta_k = theta_{k-1} + v_k.
        self.particles = wrap_angle(self.particles + rng.normal(0.0, cfg.process_noise, n))
        # Weight update with the likelihood, in logarithms.
        error = wrap_angle(z - self.particles)
        sigma = cfg.measurement_noise
        gauss = np.exp(-0.5 * (error / sigma) ** 2) / (math.sqrt(TWO_PI) * sigma)
        likelihood = (1.0 - cfg.outlier_probability) * gauss + cfg.outlier_probability / TWO_PI
        log_w = np.log(np.maximum(self.weights, _TINY)) + np.log(np.maximum(likelihood, _TINY))
        log_w -= log_w.max()
        w = np.exp(log_w)
        # Normalise.
        self.weights = w / w.sum()
        # Resampling when the effective sample size drops below N_T.
        if self.effective_sample_size < cfg.threshold:
            self._resample_and_disperse()
        self.updates += 1
        self._bearing = self._estimate(z)
        return self._bearing

    def _estimate(self, fallback: float) -> float:
        """S_k over the particles of the most-weighted direction.

        The paper flies "to the direction of the most particles": the weighted circular
        histogram (5 deg bins, smoothed over +-15 deg) gives that direction, and the
        weighted mean of the unit vectors within +-45 deg of it refines it. A mean over all
        particles would be dragged toward a reflection whenever the dispersed particles
        that happen to point at it gain weight.
        """
        bins = _MODE_BINS
        index = ((self.particles + math.pi) * (bins / TWO_PI)).astype(np.int64) % bins
        histogram = np.bincount(index, weights=self.weights, minlength=bins)
        window = np.ones(2 * _MODE_SMOOTHING + 1)
        padded = np.r_[histogram[-_MODE_SMOOTHING:], histogram, histogram[:_MODE_SMOOTHING]]
        smoothed = np.convolve(padded, window, mode="valid")
        mode = -math.pi + (int(np.argmax(smoothed)) + 0.5) * TWO_PI / bins
        near = np.abs(wrap_angle(self.particles - mode)) <= _MODE_HALF_WIDTH
        w = self.weights * near
        c = float(np.dot(w, np.cos(self.particles)))
        s = float(np.dot(w, np.sin(self.particles)))
        return math.atan2(s, c) if (c or s) else fallback

    def _resample_and_disperse(self) -> None:
        cfg = self.settings
        n = cfg.n_particles
        rng = self._rng
        self.particles = self.particles[systematic_resample(self.weights, rng)]
        self.weights = np.full(n, 1.0 / n)
        n_dispersed = int(round(cfg.dispersion_fraction * n))
        if n_dispersed:
            # Systematic resampling returns particles grouped by parent, so pick the
            # dispersed ones at random rather than a block of neighbours.
            chosen = rng.choice(n, size=n_dispersed, replace=False)
            self.particles[chosen] = rng.uniform(-math.pi, math.pi, n_dispersed)
        self.resamplings += 1
