"""Minimum-snap piecewise polynomials through waypoints (Richter, Bry and Roy; Mellinger and
Kumar), as section III-D of Mittal et al. uses them for the landing approach.

Each of the M segments is a 7th-degree polynomial per axis in its normalised time
``tau = t / T_k``. Minimising the integral of the squared snap with the waypoints fixed gives,
by the Euler-Lagrange equations, polynomials of degree 7 whose derivatives 1 to 6 are
continuous at every interior waypoint; with velocity, acceleration and jerk fixed at both ends
that is a square linear system of 8M unknowns per axis, solved here directly.

Durations come from a trapezoidal speed profile per segment, then all are scaled by one
factor so that the peak speed and acceleration meet the limits exactly: with zero end
derivatives, stretching time by ``s`` keeps the shape and divides speed by ``s`` and
acceleration by ``s**2``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

DEGREE = 7
N_COEFF = DEGREE + 1
# Samples per segment when measuring the peaks and checking collisions.
SAMPLES_PER_SEGMENT = 64


def _derivative_row(order: int, tau: float) -> np.ndarray:
    """d^order/dtau^order of [1, tau, ..., tau^7] at ``tau``."""
    n = np.arange(N_COEFF)
    factor = np.ones(N_COEFF)
    for k in range(order):
        factor *= n - k
    power = np.clip(n - order, 0, None)
    return np.where(n >= order, factor * tau**power, 0.0)


@dataclass(frozen=True, slots=True)
class Trajectory:
    """A piecewise-polynomial trajectory.

    Attributes:
        coefficients: (M, 8, D) polynomial coefficients per segment in normalised time,
            lowest power first, D axes (ENU m).
        durations: (M,) seconds per segment.
    """

    coefficients: np.ndarray
    durations: np.ndarray

    @property
    def duration(self) -> float:
        return float(self.durations.sum())

    @property
    def knots(self) -> np.ndarray:
        """(M + 1,) start time of each segment, and the end."""
        return np.concatenate([[0.0], np.cumsum(self.durations)])

    def sample(self, t: np.ndarray | float, order: int = 0) -> np.ndarray:
        """The ``order``-th time derivative at times ``t`` (clipped to the trajectory).

        Args:
            t: (T,) seconds from the start.
            order: 0 position (m), 1 velocity (m/s), 2 acceleration (m/s^2), ...

        Returns:
            (T, D) values.
        """
        t = np.clip(np.atleast_1d(np.asarray(t, dtype=np.float64)), 0.0, self.duration)
        knots = self.knots
        seg = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, len(self.durations) - 1)
        T = self.durations[seg]
        tau = (t - knots[seg]) / T
        n = np.arange(N_COEFF)
        factor = np.ones(N_COEFF)
        for k in range(order):
            factor *= n - k
        power = np.clip(n - order, 0, None)
        basis = np.where(n >= order, factor * tau[:, None] ** power, 0.0)  # (T, 8)
        values = np.einsum("tn,tnd->td", basis, self.coefficients[seg])
        return values / T[:, None] ** order

    def peaks(self) -> tuple[float, float]:
        """(highest speed m/s, highest acceleration m/s^2), sampled densely."""
        t = np.linspace(0.0, self.duration, SAMPLES_PER_SEGMENT * len(self.durations) + 1)
        speed = np.linalg.norm(self.sample(t, 1), axis=1).max()
        accel = np.linalg.norm(self.sample(t, 2), axis=1).max()
        return float(speed), float(accel)


def solve_min_snap(waypoints: np.ndarray, durations: np.ndarray) -> Trajectory:
    """The minimum-snap trajectory through ``waypoints`` with the given segment durations,
    starting and ending at rest (zero velocity, acceleration and jerk).

    Args:
        waypoints: (M + 1, D) positions, m.
        durations: (M,) seconds, each > 0.
    """
    waypoints = np.asarray(waypoints, dtype=np.float64)
    durations = np.asarray(durations, dtype=np.float64)
    m = len(durations)
    if len(waypoints) != m + 1 or m < 1 or np.any(durations <= 0):
        raise ValueError("need M + 1 waypoints and M positive durations")
    size = N_COEFF * m
    A = np.zeros((size, size))
    b = np.zeros((size, waypoints.shape[1]))
    row = 0

    def block(k: int) -> slice:
        return slice(N_COEFF * k, N_COEFF * (k + 1))

    for k in range(m):
        A[row, block(k)] = _derivative_row(0, 0.0)
        b[row] = waypoints[k]
        A[row + 1, block(k)] = _derivative_row(0, 1.0)
        b[row + 1] = waypoints[k + 1]
        row += 2
    for order in (1, 2, 3):  # at rest at both ends
        A[row, block(0)] = _derivative_row(order, 0.0)
        A[row + 1, block(m - 1)] = _derivative_row(order, 1.0)
        row += 2
    for k in range(1, m):
        # d^r/dt^r continuous: row scaled by T_{k-1}^r to keep the system well conditioned.
        ratio = durations[k - 1] / durations[k]
        for order in range(1, DEGREE):
            A[row, block(k - 1)] = _derivative_row(order, 1.0)
            A[row, block(k)] = -_derivative_row(order, 0.0) * ratio**order
            row += 1
    coefficients = np.linalg.solve(A, b).reshape(m, N_COEFF, -1)
    return Trajectory(coefficients=coefficients, durations=durations)


def trapezoid_durations(waypoints: np.ndarray, max_speed: float, max_acceleration: float):
    """(M,) seconds to fly each segment from rest to rest with a trapezoidal speed profile."""
    d = np.linalg.norm(np.diff(np.asarray(waypoints, dtype=np.float64), axis=0), axis=1)
    d = np.maximum(d, 1e-3)
    cruise = d / max_speed + max_speed / max_acceleration
    short = 2.0 * np.sqrt(d / max_acceleration)
    return np.where(d > max_speed**2 / max_acceleration, cruise, short)


def min_snap_trajectory(
    waypoints: np.ndarray, max_speed: float, max_acceleration: float
) -> Trajectory:
    """The minimum-snap trajectory through ``waypoints`` (from rest to rest) whose peak speed
    and acceleration just meet ``max_speed`` (m/s) and ``max_acceleration`` (m/s^2).

    Args:
        waypoints: (M + 1, D) positions, m, M >= 1.
    """
    if max_speed <= 0 or max_acceleration <= 0:
        raise ValueError("max_speed and max_acceleration must be > 0")
    durations = trapezoid_durations(waypoints, max_speed, max_acceleration)
    trajectory = solve_min_snap(waypoints, durations)
    speed, accel = trajectory.peaks()
    scale = max(speed / max_speed, math.sqrt(accel / max_acceleration), 1e-6)
    return solve_min_snap(waypoints, durations * scale)


def concatenate(first: Trajectory, second: Trajectory) -> Trajectory:
    """``first`` then ``second``: both rest to rest, so the joint is smooth (at rest)."""
    return Trajectory(
        coefficients=np.concatenate([first.coefficients, second.coefficients]),
        durations=np.concatenate([first.durations, second.durations]),
    )
