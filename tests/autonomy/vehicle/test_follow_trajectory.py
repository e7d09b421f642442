"""Trajectory tracking through the driver (``follow``: a position target with a velocity
feed-forward) against the embedded SITL of both personalities."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autonomy.clock import SimClock
from autonomy.vehicle import connect
from behaviors.ports import CommandStatus
from planning import min_snap_trajectory

DT = 0.05


def _tick(vehicle, clock):
    vehicle.sitl.step(DT)
    clock.advance(DT)
    return vehicle.poll()


def _until(vehicle, clock, condition, timeout):
    end = clock.now() + timeout
    while clock.now() < end:
        state = _tick(vehicle, clock)
        if condition(state):
            return state
    raise AssertionError(f"not reached in {timeout} s")


def _fly(personality: str, feed_forward: bool):
    """Take off, then track a curved minimum-snap trajectory; the largest and the final
    horizontal distance from the trajectory's sample, m, and the follow handle."""
    clock = SimClock()
    vehicle = connect(f"sim://{personality}", clock)
    try:
        _until(vehicle, clock, lambda s: s.prearm_ok, 30)
        handle = vehicle.takeoff(10.0)
        _until(vehicle, clock, lambda s: s.position[2] > 9.7, 40)
        assert handle.status is CommandStatus.ACCEPTED
        x0, y0, _ = vehicle.state.position
        waypoints = np.array([[x0, y0, 10.0], [x0 + 25, y0, 10.0], [x0 + 25, y0 + 25, 14.0]])
        trajectory = min_snap_trajectory(waypoints, max_speed=5.0, max_acceleration=2.0)
        start, errors, handles = clock.now(), [], set()
        while clock.now() - start < trajectory.duration + 3.0:
            t = clock.now() - start
            p = trajectory.sample(t)[0]
            v = trajectory.sample(t, 1)[0] if feed_forward else np.zeros(3)
            handles.add(id(h := vehicle.follow(*p, *v)))
            state = _tick(vehicle, clock)
            if t > 1.0:  # once the mode change is through
                errors.append(math.dist(state.position, p))
        assert h.status is CommandStatus.ACCEPTED, h.reason
        assert len(handles) == 1  # one command; every later sample rides on it
        return max(errors), errors[-1]
    finally:
        vehicle.close()


@pytest.mark.parametrize("personality", ["ardupilot", "px4"])
def test_follow_tracks_a_trajectory_closely_with_the_velocity_feed_forward(personality):
    worst, final = _fly(personality, feed_forward=True)
    lagging, _ = _fly(personality, feed_forward=False)
    assert final < 0.3
    assert worst < 1.5
    # The feed-forward is what lets the vehicle keep up with a moving target.
    assert worst < 0.5 * lagging


def test_follow_refuses_a_sample_that_is_not_finite():
    clock = SimClock()
    vehicle = connect("sim://ardupilot", clock)
    try:
        _until(vehicle, clock, lambda s: not s.link_lost, 5)
        handle = vehicle.follow(0.0, 0.0, math.nan, 0.0, 0.0, 0.0)
        assert handle.status is CommandStatus.DENIED and "finite" in handle.reason
    finally:
        vehicle.close()
