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


# Derivatives 0..6 of the monomials at the two ends of a segment (rows: order), and the
# monomials' first two derivatives on a fixed grid of normalised times (for the peaks): built
# once, so that assembling and measuring a trajectory is array arithmetic only.
_AT_START = np.array([_derivative_row(r, 0.0) for r in range(DEGREE)])
_AT_END = np.array([_derivative_row(r, 1.0) for r in range(DEGREE)])
_TAU = np.linspace(0.0, 1.0, SAMPLES_PER_SEGMENT + 1)
_VELOCITY_BASIS = np.array([_derivative_row(1, t) for t in _TAU])
_ACCELERATION_BASIS = np.array([_derivative_row(2, t) for t in _TAU])


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
        """(highest speed m/s, highest acceleration m/s^2), sampled at
        ``SAMPLES_PER_SEGMENT + 1`` evenly spaced times of every segment."""
        T = self.durations[:, None, None]
        velocity = (_VELOCITY_BASIS @ self.coefficients) / T
        acceleration = (_ACCELERATION_BASIS @ self.coefficients) / T**2
        speed = np.sqrt((velocity**2).sum(axis=2)).max()
        accel = np.sqrt((acceleration**2).sum(axis=2)).max()
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
    # Rows 0 .. 2M-1: each segment starts at its waypoint and ends at the next.
    blocks = A[: 2 * m].reshape(m, 2, m, N_COEFF)
    k = np.arange(m)
    blocks[k, 0, k] = _AT_START[0]
    blocks[k, 1, k] = _AT_END[0]
    b[0 : 2 * m : 2] = waypoints[:-1]
    b[1 : 2 * m : 2] = waypoints[1:]
    # Rows 2M .. 2M+5: at rest at both ends (velocity, acceleration, jerk zero).
    ends = A[2 * m : 2 * m + 6].reshape(3, 2, m, N_COEFF)
    ends[:, 0, 0] = _AT_START[1:4]
    ends[:, 1, m - 1] = _AT_END[1:4]
    if m > 1:
        # d^r/dt^r (r = 1 .. 6) continuous at each interior waypoint, each row scaled by
        # T_{k-1}^r to keep the system well conditioned.
        joints = A[2 * m + 6 :].reshape(m - 1, DEGREE - 1, m, N_COEFF)
        ratio = durations[:-1] / durations[1:]
        orders = np.arange(1, DEGREE)
        j = np.arange(m - 1)
        joints[j, :, j] = _AT_END[1:]
        joints[j, :, j + 1] = -_AT_START[1:] * ratio[:, None, None] ** orders[None, :, None]
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
    # Stretching every duration by one factor keeps the ratios the joints' rows depend on,
    # so the normalised-time coefficients stay the optimum: no second solve.
    return Trajectory(coefficients=trajectory.coefficients, durations=durations * scale)


def concatenate(first: Trajectory, second: Trajectory) -> Trajectory:
    """``first`` then ``second``: both rest to rest, so the joint is smooth (at rest)."""
    return Trajectory(
        coefficients=np.concatenate([first.coefficients, second.coefficients]),
        durations=np.concatenate([first.durations, second.durations]),
    )
