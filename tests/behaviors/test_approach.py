"""FlyApproachTrajectory: the approach along a planned trajectory, with the thesis's
climb-traverse-descent as the fallback."""

from __future__ import annotations

import math

import numpy as np
import py_trees
from behaviors_fakes import FakeVehicle
from py_trees.common import Status

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.approach import FlyApproachTrajectory
from behaviors.flight import NavigateToSite
from lsm.area import OperatingArea
from lsm.records import LandingSite
from planning import clearance_grid, plan_approach

RES = 0.5
ORIGIN = np.array([-30.0, -30.0])


def _terrain():
    top = np.zeros((120, 120))
    top[30:90, 76:84] = 30.0  # a 30 m high block between the start and the site
    return top, np.full_like(top, 0.01)


class _Planned:
    def __init__(self, trajectory):
        self.trajectory = trajectory

    @property
    def duration(self):
        return self.trajectory.duration

    def state_at(self, t):
        return tuple(self.trajectory.sample(t)[0]), tuple(self.trajectory.sample(t, 1)[0])


class MapPlanner:
    def __init__(self, top, variance):
        self.top, self.variance, self.calls = top, variance, []

    def plan(self, start, goal):
        self.calls.append((start, goal))
        plan = plan_approach(np.array(start), np.array(goal), self.top, self.variance, ORIGIN,
                             RES, radius=1.0, margin=2.0, max_speed=4.0, max_acceleration=2.0)
        return _Planned(plan.trajectory) if plan.ok else plan.reason


class NoPlan:
    def plan(self, start, goal):
        return "the site is outside the mapped area"


def _site(x, y, z=0.0):
    return LandingSite(id=1, x=x, y=y, z=z, roughness=0.0, uncertainty=0.0, size=3.0,
                       obstacle_altitude=0.0, verification_altitude=20.0, first_seen=0.0,
                       last_seen=0.0, detection_count=1)


def _run(planner, *, speed=12.0, site=(0.0, 20.0), area=None):
    clock = SimClock()
    vehicle = FakeVehicle(clock, speed=speed)
    vehicle.armed, vehicle.position = True, (0.0, 0.0, 12.0)
    writer = py_trees.blackboard.Client(name="test")
    writer.register_key(key=keys.LANDING_SITE, access=py_trees.common.Access.WRITE)
    writer.register_key(key=keys.CLEAR_ALTITUDE, access=py_trees.common.Access.WRITE)
    writer.set(keys.LANDING_SITE, _site(*site))
    writer.set(keys.CLEAR_ALTITUDE, 42.0)
    trajectory = FlyApproachTrajectory("Approach trajectory", vehicle, clock, planner,
                                       min_height=10.0, area=area)
    thesis = NavigateToSite("NavigateToSite", vehicle, clock)
    root = py_trees.composites.Selector("Approach", memory=True,
                                        children=[trajectory, thesis])
    tree = py_trees.trees.BehaviourTree(root)
    path = []
    for _ in range(4000):
        tree.tick()
        if root.status is not Status.RUNNING:
            break
        clock.advance(0.05)
        vehicle.step(0.05)
        path.append(vehicle.position)
    return root, trajectory, thesis, vehicle, np.array(path)


def test_the_vehicle_flies_around_the_block_along_the_trajectory_and_arrives_over_the_site():
    top, var = _terrain()
    planner = MapPlanner(top, var)
    root, trajectory, thesis, vehicle, path = _run(planner)
    assert root.status is Status.SUCCESS and trajectory.status is Status.SUCCESS
    assert thesis.status is Status.INVALID  # the fallback never ran
    assert not vehicle.gotos() and any(n == "follow" for n, _ in vehicle.commands)
    # It ended over the site at min_height above it, having come down from 12 m on the way.
    assert math.hypot(path[-1][0], path[-1][1] - 20.0) < 1.0 and abs(path[-1][2] - 10.0) < 0.5
    # Around the block, never over it, and clear of it by the radius and margin.
    clear = clearance_grid(top, var, RES, 1.0)
    cells = np.floor((path[:, :2] - ORIGIN) / RES).astype(int)
    assert np.all(path[:, 2] > clear[cells[:, 0], cells[:, 1]] + 1.5)
    assert path[:, 2].max() < 13.0
    assert planner.calls[0][1] == (0.0, 20.0, 10.0)  # site z 0 + min_height


def test_without_a_trajectory_the_thesis_approach_flies_over_the_clear_altitude():
    root, trajectory, thesis, vehicle, path = _run(NoPlan())
    # (the Selector resets a failed child once another succeeds; its reason stays)
    assert "outside the mapped area" in trajectory.feedback_message
    assert root.status is Status.SUCCESS and thesis.status is Status.SUCCESS
    assert vehicle.gotos() and path[:, 2].max() > 41.0  # climbed to the clear altitude


def test_a_vehicle_that_cannot_keep_up_leaves_the_trajectory_to_the_fallback():
    top, var = _terrain()
    root, trajectory, thesis, vehicle, _ = _run(MapPlanner(top, var), speed=0.5)
    assert "off the trajectory" in trajectory.feedback_message
    assert vehicle.gotos()
    assert root.status is Status.SUCCESS and thesis.status is Status.SUCCESS


def test_a_trajectory_leaving_the_operating_area_is_refused_for_the_straight_traverse():
    top, var = _terrain()
    # A strip narrower than the block: going around it leaves the area, going over does not.
    strip = OperatingArea(((-10, -10), (10, -10), (10, 30), (-10, 30)), margin=1.0)
    root, trajectory, thesis, vehicle, path = _run(MapPlanner(top, var), area=strip)
    assert "leaves the geofence" in trajectory.feedback_message
    assert root.status is Status.SUCCESS and thesis.status is Status.SUCCESS
    assert not any(n == "follow" for n, _ in vehicle.commands)
    assert strip.contains(path[:, :2]).all()
