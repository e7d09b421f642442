"""The flight's frame (autonomy.vehicle.home.FlightFrame): it follows the vehicle's home until
kept, then stays, and records each move of home beyond the tolerance, measured from the last
home it recorded (so a home creeping in small steps is still seen)."""

from __future__ import annotations

import pytest

from autonomy.vehicle.home import HOME_MOVE_TOLERANCE, FlightFrame

A = (47.0, 8.0, 488.0)
B = (47.0003, 8.0, 490.0)


def test_follows_home_until_kept_then_records_moves():
    frame = FlightFrame()
    frame.on_home(A, (0.0, 0.0, 0.0), 1.0)
    frame.on_home(B, (5.0, 0.0, 0.0), 2.0)  # moved on the ground: followed
    assert (frame.origin, frame.origin_ned, frame.moves) == (B, (5.0, 0.0, 0.0), [])
    frame.keep()
    frame.on_home(A, (35.0, 0.0, -2.0), 3.0)
    assert (frame.origin, frame.origin_ned) == (B, (5.0, 0.0, 0.0))
    (move,) = frame.moves
    assert (move.time, move.previous, move.home) == (3.0, B, A)
    assert move.distance == pytest.approx(30.0665, abs=1e-4)
    assert move.position == pytest.approx((0.0, 30.0, 2.0))  # north 30 m, 2 m up, in ENU


def test_kept_before_any_home_keeps_the_first_one():
    frame = FlightFrame()
    frame.keep()
    assert frame.origin is None
    frame.on_home(A, (1.0, 2.0, 0.0), 1.0)
    frame.on_home(B, (9.0, 2.0, 0.0), 2.0)
    assert frame.origin_ned == (1.0, 2.0, 0.0)
    assert [m.distance for m in frame.moves] == [8.0]


def test_small_steps_are_one_move_once_they_add_up():
    frame = FlightFrame()
    frame.on_home(A, (0.0, 0.0, 0.0), 0.0)
    frame.keep()
    step = HOME_MOVE_TOLERANCE * 0.6
    for i in range(1, 4):
        frame.on_home(A, (i * step, 0.0, 0.0), float(i))
    assert [m.time for m in frame.moves] == [2.0]
