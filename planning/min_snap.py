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

A single rest-to-rest polynomial spends most of its time speeding up and slowing down: its
peak speed is about twice its mean, so a long leg limited by its speed (a descent at the
autopilot's 1.5 m/s) takes twice as long as the autopilot's own trapezoid. :func:`cruise_trajectory`
therefore splits each leg into pieces about 1.5 s long, placed where a gentler trapezoid
would be at those times: the minimum-snap curve through them cruises near the limit in the
middle of the leg.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.linalg.lapack import dgbsv as _gbsv

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
        legs: (M,) int64 the leg (pair of consecutive waypoints given) each segment flies, or
            None when every segment is a leg of its own.
    """

    coefficients: np.ndarray
    durations: np.ndarray
    legs: np.ndarray | None = None

    def leg_of(self, segment: int) -> int:
        """The leg of the waypoints that ``segment`` belongs to."""
        return segment if self.legs is None else int(self.legs[segment])

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
        return _peaks(*self._sampled_derivatives())[:2]

    def vertical_peaks(self) -> tuple[float, float]:
        """(highest climb rate, highest descent rate), m/s, both >= 0, of the last axis (up),
        sampled as :meth:`peaks` samples."""
        return _peaks(*self._sampled_derivatives())[2:]

    def _sampled_derivatives(self) -> tuple[np.ndarray, np.ndarray]:
        T = self.durations[:, None, None]
        velocity = (_VELOCITY_BASIS @ self.coefficients) / T
        acceleration = (_ACCELERATION_BASIS @ self.coefficients) / T**2
        return velocity, acceleration


def _peaks(velocity: np.ndarray, acceleration: np.ndarray) -> tuple[float, float, float,
                                                                     float]:
    """(speed, acceleration, climb rate, descent rate) peaks of sampled derivatives (M, S, D);
    the vertical two are of the last axis (up), both >= 0."""
    up = velocity[:, :, -1]
    return (float(np.sqrt((velocity**2).sum(axis=2)).max()),
            float(np.sqrt((acceleration**2).sum(axis=2)).max()),
            float(max(up.max(), 0.0)), float(max(-up.min(), 0.0)))


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
    coefficients = _solve_block_banded(A, b).reshape(m, N_COEFF, -1)
    return Trajectory(coefficients=coefficients, durations=durations)


def _first_unknowns(m: int) -> np.ndarray:
    """The first unknown each row of :func:`solve_min_snap`'s system touches (rows in the
    order it writes them: waypoints, ends at rest, joints)."""
    k = np.arange(m)
    waypoint_rows = np.repeat(N_COEFF * k, 2)
    orders = np.arange(1, 4)
    end_rows = np.stack([orders, N_COEFF * (m - 1) + orders], axis=1).ravel()
    joint_rows = (N_COEFF * k[:-1, None] + np.arange(1, DEGREE)[None, :]).ravel()
    return np.concatenate([waypoint_rows, end_rows, joint_rows])


@lru_cache(maxsize=64)
def _band_layout(m: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int, int]:
    """Where :func:`solve_min_snap`'s system of ``m`` segments goes in LAPACK's band storage,
    which depends on ``m`` alone: (row order, source rows, columns, band rows, lower and
    upper bandwidths), the band rows offset by ``lower`` for gbsv's working space."""
    n = N_COEFF * m
    first = _first_unknowns(m)
    order = np.argsort(first, kind="stable")
    first = first[order]
    rows = np.repeat(np.arange(n), 2 * N_COEFF)
    cols = (first[:, None] + np.arange(2 * N_COEFF)[None, :]).ravel()
    inside = cols < n
    rows, cols = rows[inside], cols[inside]
    lower, upper = int(max(0, (rows - cols).max())), int(max(0, (cols - rows).max()))
    return order, order[rows], cols, lower + upper + rows - cols, lower, upper


def _solve_block_banded(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``A x = b`` for :func:`solve_min_snap`'s system: each row touches at most two
    neighbouring segments' coefficients, so with its rows sorted by their first unknown the
    matrix is banded, and a banded LU (LAPACK gbsv, as scipy's solve_banded calls it) solves
    it in time linear in the segments, without the dense solver's threads (which on a busy
    machine cost tens of milliseconds for 32 segments)."""
    n = len(A)
    m = n // N_COEFF
    if m <= 4:
        return np.linalg.solve(A, b)
    order, source, cols, band_rows, lower, upper = _band_layout(m)
    bands = np.zeros((2 * lower + upper + 1, n))
    bands[band_rows, cols] = A[source, cols]
    _, _, x, info = _gbsv(lower, upper, bands, b[order], overwrite_ab=True, overwrite_b=True)
    if info != 0:
        raise np.linalg.LinAlgError(f"singular minimum-snap system (gbsv info {info})")
    return x


def trapezoid_durations(waypoints: np.ndarray, max_speed: float, max_acceleration: float):
    """(M,) seconds to fly each segment from rest to rest with a trapezoidal speed profile."""
    d = np.linalg.norm(np.diff(np.asarray(waypoints, dtype=np.float64), axis=0), axis=1)
    d = np.maximum(d, 1e-3)
    cruise = d / max_speed + max_speed / max_acceleration
    short = 2.0 * np.sqrt(d / max_acceleration)
    return np.where(d > max_speed**2 / max_acceleration, cruise, short)


def min_snap_trajectory(
    waypoints: np.ndarray,
    max_speed: float,
    max_acceleration: float,
    max_climb: float | None = None,
    max_descent: float | None = None,
) -> Trajectory:
    """The minimum-snap trajectory through ``waypoints`` (from rest to rest) whose peak speed
    and acceleration just meet ``max_speed`` (m/s) and ``max_acceleration`` (m/s^2), or its
    climb or descent rate (the last axis, up) ``max_climb`` / ``max_descent`` (m/s) if that
    binds first: autopilots climb and descend slower than they fly level.

    Args:
        waypoints: (M + 1, D) positions, m, M >= 1.
    """
    limits = [max_speed, max_acceleration] + [v for v in (max_climb, max_descent) if v is not None]
    if min(limits) <= 0:
        raise ValueError("the speed, acceleration, climb and descent limits must be > 0")
    durations = trapezoid_durations(waypoints, max_speed, max_acceleration)
    trajectory = solve_min_snap(waypoints, durations)
    return _within_limits(trajectory, max_speed, max_acceleration, max_climb, max_descent)


def _within_limits(trajectory: Trajectory, max_speed, max_acceleration, max_climb,
                   max_descent, legs: np.ndarray | None = None) -> Trajectory:
    """``trajectory`` stretched in time until its peak speed, acceleration, climb or descent
    rate (whichever binds first) just meets its limit."""
    speed, accel, climb, descent = _peaks(*trajectory._sampled_derivatives())
    ratios = [speed / max_speed, math.sqrt(accel / max_acceleration), 1e-6]
    if trajectory.coefficients.shape[2] == 3:
        ratios += [climb / max_climb if max_climb else 0.0,
                   descent / max_descent if max_descent else 0.0]
    # Stretching every duration by one factor keeps the ratios the joints' rows depend on,
    # so the normalised-time coefficients stay the optimum: no second solve.
    return Trajectory(coefficients=trajectory.coefficients,
                      durations=trajectory.durations * max(ratios), legs=legs)


def concatenate(first: Trajectory, second: Trajectory) -> Trajectory:
    """``first`` then ``second``: both rest to rest, so the joint is smooth (at rest). The
    second's legs are numbered after the first's."""
    def legs(t: Trajectory) -> np.ndarray:
        return np.arange(len(t.durations)) if t.legs is None else t.legs

    first_legs = legs(first)
    return Trajectory(
        coefficients=np.concatenate([first.coefficients, second.coefficients]),
        durations=np.concatenate([first.durations, second.durations]),
        legs=np.concatenate([first_legs, legs(second) + first_legs.max() + 1]),
    )


# Pieces of a leg, seconds apart at the trapezoid's pace; at most this many per trajectory
# (the linear system grows with their square).
PIECE_TIME = 1.5
MAX_PIECES = 16
# The trapezoid placing the pieces accelerates at this share of the limit: the smooth curve
# through a sharper one overshoots its acceleration and must be stretched more.
GENTLE = 0.5


def _leg_speed(direction: np.ndarray, max_speed, max_climb, max_descent) -> float:
    v = max_speed
    if len(direction) == 3:
        up = direction[2]
        if up > 1e-9 and max_climb:
            v = min(v, max_climb / up)
        elif up < -1e-9 and max_descent:
            v = min(v, max_descent / -up)
    return v


def cruise_trajectory(
    waypoints: np.ndarray,
    max_speed: float,
    max_acceleration: float,
    max_climb: float | None = None,
    max_descent: float | None = None,
) -> Trajectory:
    """Like :func:`min_snap_trajectory` through ``waypoints`` (rest to rest, within the same
    limits), but each leg split into pieces so that the vehicle cruises along it rather than
    speeding up and slowing down all the way (see the module's docstring). Its ``legs`` map
    each segment to the leg of ``waypoints`` it flies."""
    waypoints = np.asarray(waypoints, dtype=np.float64)
    gentle = GENTLE * max_acceleration
    plans = []
    for a, b in zip(waypoints[:-1], waypoints[1:], strict=True):
        d = max(float(np.linalg.norm(b - a)), 1e-3)
        v = _leg_speed((b - a) / d, max_speed, max_climb, max_descent)
        ramp = v / gentle
        if d > v * ramp:
            total = d / v + ramp
        else:
            ramp = math.sqrt(d / gentle)
            v, total = gentle * ramp, 2.0 * ramp
        plans.append((a, b, d, v, ramp, total))
    piece = max(PIECE_TIME, sum(p[-1] for p in plans) / MAX_PIECES)
    # Every leg's pieces at once: per leg, the times np.linspace(0, total, n + 1) would give
    # (index * step, the last exactly total) and the trapezoid's distance at each, with the
    # same float operations as one leg at a time.
    a, b, d, v, ramp, total = (np.array(column) for column in zip(*plans, strict=True))
    n = np.array([max(1, int(math.ceil(p[-1] / piece - 1e-9))) for p in plans])
    cruise_start = [0.5 * gentle * p[4] ** 2 for p in plans]
    leg = np.repeat(np.arange(len(plans)), n)
    first = np.concatenate([[0], np.cumsum(n)[:-1]])
    index = np.arange(leg.size) - first[leg] + 1  # 1 .. n within each leg
    t = index * (total / n)[leg]
    last = index == n[leg]
    t[last] = total
    before = np.where(index == 1, 0.0, np.concatenate([[0.0], t[:-1]]))
    durations = t - before
    d_, v_, ramp_, total_ = d[leg], v[leg], ramp[leg], total[leg]
    c = 0.5 * gentle
    s = np.where(t < ramp_, c * t**2,
                 np.where(t < total_ - ramp_, np.array(cruise_start)[leg] + v_ * (t - ramp_),
                          d_ - c * (total_ - t) ** 2))
    points = np.concatenate([waypoints[:1],
                             a[leg] + np.clip(s, 0.0, d_)[:, None] / d_[:, None] * (b - a)[leg]])
    points[-1] = waypoints[-1]
    trajectory = solve_min_snap(points, durations)
    return _within_limits(trajectory, max_speed, max_acceleration, max_climb, max_descent,
                          legs=leg.astype(np.int64))
