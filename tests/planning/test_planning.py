"""Approach planning (planning/): grid path, line of sight, minimum snap, checked on the map."""

from __future__ import annotations

import math

import numpy as np
import pytest

from planning import clearance_grid, free_cells, min_snap_trajectory, plan_approach, plan_path
from planning.grid_path import visible
from planning.min_snap import solve_min_snap

RES = 0.5


def _flat(n=80, height=0.0):
    return np.full((n, n), height), np.full((n, n), 0.01)


def test_clearance_is_the_highest_top_within_the_radius_and_unknown_is_never_clear():
    top, var = _flat(21)
    top[10, 10] = 8.0
    top[0, 20] = np.nan
    clear = clearance_grid(top, np.zeros_like(var), RES, radius=1.0, k_sigma=0.0)
    # Cells within 1 m (2 cells) of the tall one carry its height, beyond it the ground's.
    assert clear[10, 12] == 8.0 and clear[11, 11] == 8.0
    assert clear[10, 13] == 0.0 and clear[12, 12] == 0.0
    # The unknown cell, its neighbourhood and the grid's edge are never passable.
    assert np.isinf(clear[0, 20]) and np.isinf(clear[1, 19])
    assert np.isinf(clear[0, 5]) and np.isfinite(clear[2, 5])


def test_uncertainty_raises_the_clearance():
    top, _ = _flat(9)
    var = np.full_like(top, 0.25)  # sigma 0.5 m
    clear = clearance_grid(top, var, RES, radius=0.0, k_sigma=2.0)
    assert np.allclose(clear, 1.0)


def _wall_with_gap(n=80, gap=(60, 66), height=20.0):
    top, var = _flat(n)
    top[40, :] = height
    top[40, gap[0]:gap[1]] = 0.0
    return top, var


def test_path_goes_through_the_gap_with_few_waypoints_that_see_each_other():
    top, var = _wall_with_gap()
    free = free_cells(clearance_grid(top, var, RES, radius=0.5), altitude=10.0, margin=1.0)
    origin = np.zeros(2)
    start, goal = np.array([5.0, 10.0]), np.array([35.0, 10.0])
    path = plan_path(free, origin, RES, start, goal)
    assert path is not None
    assert np.allclose(path.waypoints[0], start) and np.allclose(path.waypoints[-1], goal)
    # The wall is at x = 20..20.5 m; it is crossed only where the gap is (y 30..33 m).
    crossing = path.cells[path.cells[:, 0] == 40]
    assert len(crossing) and np.all((crossing[:, 1] >= 60) & (crossing[:, 1] < 66))
    assert len(path.waypoints) <= 5
    for a, b in zip(path.waypoints[:-1], path.waypoints[1:], strict=True):
        assert visible(free, origin, RES, a, b[None])[0]
    assert path.length > np.hypot(*(goal - start))


def test_no_path_when_the_wall_is_closed_or_the_goal_is_off_the_map():
    top, var = _wall_with_gap(gap=(0, 0))
    free = free_cells(clearance_grid(top, var, RES, radius=0.5), altitude=10.0, margin=1.0)
    assert plan_path(free, np.zeros(2), RES, np.array([5.0, 10.0]), np.array([35, 10.0])) is None
    assert plan_path(free, np.zeros(2), RES, np.array([5.0, 10.0]), np.array([95, 10.0])) is None


def _snap_cost_matrix(duration: float) -> np.ndarray:
    """Integral over [0, T] of the squared 4th derivative, as a quadratic form in the
    coefficients of t (not of normalised time): an independent formulation."""
    q = np.zeros((8, 8))
    for i in range(4, 8):
        for j in range(4, 8):
            ci = math.factorial(i) / math.factorial(i - 4)
            cj = math.factorial(j) / math.factorial(j - 4)
            q[i, j] = ci * cj * duration ** (i + j - 7) / (i + j - 7)
    return q


def _row(order, t):
    return np.array([
        math.factorial(n) / math.factorial(n - order) * t ** (n - order) if n >= order else 0.0
        for n in range(8)
    ])


def test_min_snap_equals_the_quadratic_programme_it_solves():
    """The direct C6 solve must equal the minimum of the snap integral under the waypoint,
    rest-to-rest and C3 continuity constraints (KKT system of the QP)."""
    waypoints = np.array([[0.0, 0.0], [4.0, 1.0], [6.0, 5.0], [10.0, 6.0]])
    durations = np.array([2.0, 1.5, 2.5])
    traj = solve_min_snap(waypoints, durations)
    m = len(durations)
    Q = np.zeros((8 * m, 8 * m))
    rows, rhs = [], []
    for k, T in enumerate(durations):
        Q[8 * k:8 * k + 8, 8 * k:8 * k + 8] = _snap_cost_matrix(T)
        for t, w in ((0.0, waypoints[k]), (T, waypoints[k + 1])):
            r = np.zeros(8 * m)
            r[8 * k:8 * k + 8] = _row(0, t)
            rows.append(r)
            rhs.append(w)
    for order in (1, 2, 3):
        for k, t in ((0, 0.0), (m - 1, durations[-1])):
            r = np.zeros(8 * m)
            r[8 * k:8 * k + 8] = _row(order, t)
            rows.append(r)
            rhs.append(np.zeros(2))
    for k in range(1, m):
        for order in (1, 2, 3):
            r = np.zeros(8 * m)
            r[8 * (k - 1):8 * k] = _row(order, durations[k - 1])
            r[8 * k:8 * k + 8] = -_row(order, 0.0)
            rows.append(r)
            rhs.append(np.zeros(2))
    A, b = np.array(rows), np.array(rhs)
    kkt = np.block([[2 * Q, A.T], [A, np.zeros((len(A), len(A)))]])
    solution = np.linalg.solve(kkt, np.vstack([np.zeros((8 * m, 2)), b]))[: 8 * m]
    t = np.linspace(0.0, durations.sum(), 400)
    knots = np.concatenate([[0.0], np.cumsum(durations)])
    seg = np.clip(np.searchsorted(knots, t, side="right") - 1, 0, m - 1)
    local = t - knots[seg]
    expected = np.array([_row(0, lt) @ solution[8 * s:8 * s + 8] for lt, s in zip(local, seg,
                                                                                   strict=True)])
    assert np.allclose(traj.sample(t), expected, atol=1e-6)


def test_min_snap_passes_the_waypoints_smoothly_from_rest_to_rest_within_the_limits():
    waypoints = np.array([[0.0, 0.0, 10.0], [15.0, 0.0, 10.0], [15.0, 20.0, 8.0]])
    traj = min_snap_trajectory(waypoints, max_speed=5.0, max_acceleration=2.0)
    assert np.allclose(traj.sample(traj.knots), waypoints, atol=1e-6)
    for order in (1, 2, 3):
        ends = traj.sample(np.array([0.0, traj.duration]), order)
        assert np.allclose(ends, 0.0, atol=1e-6)
    eps = 1e-7
    inner = traj.knots[1]
    for order in (1, 2, 3, 4):
        left = traj.sample(inner - eps, order)
        right = traj.sample(inner + eps, order)
        assert np.allclose(left, right, atol=1e-3 * max(1.0, np.abs(left).max()))
    speed, accel = traj.peaks()
    assert speed <= 5.0 * 1.0001 and accel <= 2.0 * 1.0001
    assert max(speed / 5.0, accel / 2.0) == pytest.approx(1.0, rel=1e-6)


def test_approach_avoids_a_tower_between_vehicle_and_site_and_stays_above_the_map():
    top, var = _flat(120)
    top[30:90, 76:84] = 30.0  # a block 30 m wide, 30 m high between start and site
    origin = np.array([-30.0, -30.0])
    start, goal = np.array([0.0, 0.0, 12.0]), np.array([0.0, 20.0, 10.0])
    plan = plan_approach(start, goal, top, var, origin, RES, radius=1.0, margin=2.0,
                         max_speed=4.0, max_acceleration=2.0)
    assert plan.ok, plan.reason
    traj = plan.trajectory
    assert np.allclose(traj.sample(0.0)[0], start) and np.allclose(traj.sample(traj.duration)[0],
                                                                      goal)
    t = np.linspace(0.0, traj.duration, 2000)
    p = traj.sample(t)
    clear = clearance_grid(top, var, RES, 1.0)
    cells = np.floor((p[:, :2] - origin) / RES).astype(int)
    assert np.all(p[:, 2] > clear[cells[:, 0], cells[:, 1]] + 2.0 - 1e-6)
    # It went around the block, not over it.
    assert p[:, 2].max() < 12.5
    assert len(plan.waypoints) >= 3


def test_open_ground_gives_a_straight_two_point_approach():
    top, var = _flat(80)
    plan = plan_approach(np.array([5.0, 5.0, 20.0]), np.array([30.0, 30.0, 20.0]), top, var,
                         np.zeros(2), RES, radius=1.0, margin=2.0, max_speed=5.0,
                         max_acceleration=2.0)
    assert plan.ok and len(plan.waypoints) == 2
    p = plan.trajectory.sample(np.linspace(0, plan.trajectory.duration, 50))
    # On the straight line between the two points.
    d = p[:, :2] - np.array([5.0, 5.0])
    assert np.allclose(d[:, 0], d[:, 1], atol=1e-6)


def test_unknown_terrain_or_a_closed_wall_gives_a_reason_instead_of_a_trajectory():
    top, var = _flat(80)
    top[:, 30:35] = np.nan
    plan = plan_approach(np.array([5.0, 5.0, 20.0]), np.array([5.0, 30.0, 20.0]), top, var,
                         np.zeros(2), RES, radius=1.0, margin=2.0, max_speed=5.0,
                         max_acceleration=2.0)
    assert not plan.ok and "no path" in plan.reason


def test_a_ridge_across_the_map_is_crossed_straight_over_with_the_margin_and_the_goal_raised():
    # Nothing leads around a 6 m ridge at the goal's 4 m: the approach goes straight over,
    # margin (3 m) above the ridge's top + 2 sigma, and ends that high over the goal.
    top, var = _flat(80)
    top[:, 30:34] = 6.0
    plan = plan_approach(np.array([5.0, 5.0, 20.0]), np.array([5.0, 30.0, 4.0]), top, var,
                         np.zeros(2), RES, radius=1.0, margin=3.0, max_speed=5.0,
                         max_acceleration=2.0)
    assert plan.ok and len(plan.waypoints) == 2
    p = plan.trajectory.sample(np.linspace(0, plan.trajectory.duration, 400))
    near = np.abs(p[:, 1] - 16.0) < 2.0 + 1.0  # over the ridge (y 15 .. 17) or within radius
    assert p[near, 2].min() > 6.0 + 2 * 0.1 + 3.0
    assert p[-1, 2] == pytest.approx(6.0 + 2 * 0.1 + 3.0, abs=0.2)  # the goal, raised


def test_from_below_the_goal_the_vehicle_climbs_over_its_start_before_it_goes():
    """After a failed verification the vehicle hovers low; the next approach climbs to the
    goal's altitude over where it is, then flies, never lower than that on the way."""
    top, var = _flat(120)
    top[40:80, 40:80] = 6.0  # a 6 m block between the two sites
    top[60, 20] = 1.0  # a rock under the vehicle: the climb starts above it
    origin = np.array([-30.0, -30.0])
    start, goal = np.array([-20.0, 0.0, 3.5]), np.array([20.0, 0.0, 10.0])
    plan = plan_approach(start, goal, top, var, origin, RES, radius=1.0, margin=2.0,
                         max_speed=4.0, max_acceleration=2.0)
    assert plan.ok, plan.reason
    assert np.allclose(plan.waypoints[1], [-20.0, 0.0, 10.0])
    p = plan.trajectory.sample(np.linspace(0.0, plan.trajectory.duration, 1000))
    away = np.hypot(p[:, 0] + 20.0, p[:, 1]) > 0.5
    assert p[away, 2].min() > 9.0  # left the start column only once up
    assert p[:, 2].max() < 10.5  # and went over the 6 m block, not around or far above
