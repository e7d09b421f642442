"""The fast approach planner keeps the slow one's guarantees: the clearance is the disc maximum
(scipy's maximum_filter as the oracle), the straight line is taken only when it is clear, the
coarse search never passes where the map's own cells are blocked, and narrow gaps are still
found."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage

from planning import clearance_grid, plan_approach
from planning.clearance import clearance_at, obstacle_height, pooled_clearance


def _oracle(top, variance, resolution, radius, k_sigma=2.0):
    height = obstacle_height(top, variance, k_sigma)
    reach = int(math.ceil(radius / resolution))
    offsets = np.arange(-reach, reach + 1) * resolution
    disc = np.hypot(offsets[:, None], offsets[None, :]) <= radius + 1e-9
    return ndimage.maximum_filter(height, footprint=disc, mode="constant", cval=np.inf)


def _rocky(rng, n=90, unknown=0.01):
    top = rng.gamma(1.0, 0.3, (n, n))
    top[rng.random((n, n)) < 0.01] = 15.0  # tall rocks
    top[rng.random((n, n)) < unknown] = np.nan
    return top, rng.uniform(0.0, 0.05, (n, n))


@pytest.mark.parametrize("radius,resolution", [(1.5, 0.25), (1.0, 0.5), (2.3, 0.3), (0.2, 0.25)])
def test_clearance_everywhere_and_at_cells_equals_the_disc_maximum_filter(radius, resolution):
    rng = np.random.default_rng(7)
    top, var = _rocky(rng)
    expected = _oracle(top, var, resolution, radius)
    assert np.array_equal(clearance_grid(top, var, resolution, radius), expected)
    cells = rng.integers(-5, 95, (300, 2))  # some outside the grid
    inside = np.all((cells >= 0) & (cells < 90), axis=1)
    want = np.full(len(cells), np.inf)
    want[inside] = expected[cells[inside, 0], cells[inside, 1]]
    got = clearance_at(obstacle_height(top, var, 2.0), cells, radius / resolution)
    assert np.array_equal(got, want)


@pytest.mark.parametrize("factor", [2, 3, 4])
def test_a_coarse_cell_is_never_lower_than_a_fine_cell_it_covers(factor):
    rng = np.random.default_rng(factor)
    top, var = _rocky(rng, n=91)
    fine = _oracle(top, var, 0.25, 1.5)
    coarse = pooled_clearance(obstacle_height(top, var, 2.0), 1.5 / 0.25, factor)
    covering = np.kron(coarse, np.ones((factor, factor)))[:91, :91]
    assert np.all(covering >= fine)


def _samples_clear(plan, top, var, origin, resolution, radius, margin):
    traj = plan.trajectory
    p = traj.sample(np.linspace(0.0, traj.duration, 4000))
    clear = _oracle(top, var, resolution, radius)
    cells = np.floor((p[:, :2] - origin) / resolution).astype(int)
    start = cells[0]
    away = ~np.all(cells == start, axis=1)
    return np.all(p[away, 2] > clear[cells[away, 0], cells[away, 1]] + margin)


def test_plans_over_random_rock_fields_never_come_closer_than_the_margin():
    origin, resolution, radius, margin = np.array([-20.0, -20.0]), 0.25, 1.5, 2.0
    planned = detoured = 0
    for seed in range(12):
        rng = np.random.default_rng(100 + seed)
        top, var = rng.gamma(1.0, 0.3, (160, 160)), rng.uniform(0.0, 0.05, (160, 160))
        top[rng.random(top.shape) < 0.0008] = 20.0
        top[rng.random(top.shape) < 0.0003] = np.nan
        wall = rng.integers(40, 120)
        top[wall:wall + 4, rng.integers(0, 80):rng.integers(90, 160)] = 30.0
        start = np.array([*rng.uniform(-14.0, 14.0, 2), 12.0])
        goal = np.array([*rng.uniform(-14.0, 14.0, 2), 8.0])
        plan = plan_approach(start, goal, top, var, origin, resolution, radius=radius,
                             margin=margin, max_speed=5.0, max_acceleration=2.0)
        if plan.ok:
            planned += 1
            detoured += len(plan.waypoints) > 2
            assert _samples_clear(plan, top, var, origin, resolution, radius, margin)
        else:
            assert plan.reason
    assert planned >= 6 and detoured >= 3  # the fields exercise both the line and the search


def test_the_straight_line_is_not_taken_through_a_single_tall_rock():
    n, resolution = 120, 0.25
    top, var = np.zeros((n, n)), np.full((n, n), 0.01)
    top[60, 60] = 20.0  # one cell on the line from (2, 15) to (28, 15)
    origin = np.zeros(2)
    plan = plan_approach(np.array([2.0, 15.0, 10.0]), np.array([28.0, 15.0, 10.0]), top, var,
                         origin, resolution, radius=1.0, margin=1.0, max_speed=5.0,
                         max_acceleration=2.0)
    assert plan.ok and len(plan.waypoints) > 2
    assert _samples_clear(plan, top, var, origin, resolution, 1.0, 1.0)


def test_a_gap_too_narrow_for_the_coarse_search_is_found_on_the_maps_cells():
    """A 3.5 m gap in a wall passes a 1.5 m vehicle at 0.25 m cells but not the coarse grid's
    extra margin: the planner falls back to the fine search rather than saying no path."""
    n, resolution = 160, 0.25
    top, var = np.zeros((n, n)), np.full((n, n), 0.0)
    top[78:82, :] = 30.0
    top[78:82, 72:86] = 0.0  # the gap: y = 18 .. 21.5 m
    origin = np.zeros(2)
    coarse = pooled_clearance(obstacle_height(top, var, 2.0), 1.5 / resolution, 3)
    assert np.all(coarse[26:28, :] + 2.0 >= 10.0)  # closed on the coarse grid
    plan = plan_approach(np.array([10.0, 19.8, 10.0]), np.array([30.0, 19.8, 10.0]), top, var,
                         origin, resolution, radius=1.5, margin=2.0, max_speed=5.0,
                         max_acceleration=2.0)
    assert plan.ok, plan.reason
    assert _samples_clear(plan, top, var, origin, resolution, 1.5, 2.0)


def test_a_descending_trajectory_keeps_to_the_autopilots_descent_rate():
    """From the cruise altitude down to above the site: the descent rate binds before the
    speed, and the whole path stays at or above the site's end altitude."""
    from planning import min_snap_trajectory

    waypoints = np.array([[0.0, 0.0, 30.0], [12.0, 5.0, 10.0]])
    traj = min_snap_trajectory(waypoints, 5.0, 2.0, max_climb=2.5, max_descent=1.5)
    climb, descent = traj.vertical_peaks()
    speed, accel = traj.peaks()
    assert descent == pytest.approx(1.5, rel=1e-6) and climb < 1e-9
    assert speed < 5.0 and accel < 2.0
    p = traj.sample(np.linspace(0.0, traj.duration, 500))
    assert p[:, 2].min() >= 10.0 - 1e-6 and p[:, 2].max() <= 30.0 + 1e-6
    top, var = np.zeros((160, 160)), np.full((160, 160), 0.01)
    plan = plan_approach(np.array([5.0, 5.0, 30.0]), np.array([30.0, 20.0, 10.0]), top, var,
                         np.zeros(2), 0.25, radius=1.5, margin=2.0, max_speed=5.0,
                         max_acceleration=2.0, max_climb=2.5, max_descent=1.5)
    assert plan.ok and plan.trajectory.vertical_peaks()[1] <= 1.5 + 1e-9


def test_many_segments_still_pass_every_waypoint_smoothly():
    """Long trajectories are solved as a banded system: the same conditions hold."""
    from planning.min_snap import solve_min_snap, trapezoid_durations

    waypoints = np.random.default_rng(0).uniform(0.0, 30.0, (13, 3))
    traj = solve_min_snap(waypoints, trapezoid_durations(waypoints, 5.0, 2.0))
    assert np.allclose(traj.sample(traj.knots), waypoints, atol=1e-6)
    for inner in traj.knots[1:-1]:
        for order in (1, 2, 3, 4):
            left, right = traj.sample(inner - 1e-7, order), traj.sample(inner + 1e-7, order)
            assert np.allclose(left, right, atol=1e-3 * max(1.0, np.abs(left).max()))
