"""RetryWhileBattery alone: py_trees' Retry bounded by the battery a try is expected to cost."""

from __future__ import annotations

import py_trees
import pytest
from behaviors_fakes import FakeVehicle
from py_trees.common import Access, Status

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.decorators import RetryWhileBattery


class Try(py_trees.behaviour.Behaviour):
    """One try: drains the vehicle's battery by the next of ``costs`` (% points) over two
    ticks, then fails (or succeeds on the try numbered ``succeed_on``, counting from 1)."""

    def __init__(self, vehicle: FakeVehicle, costs: list[float], succeed_on: int = 0) -> None:
        super().__init__(name="Try")
        self.vehicle = vehicle
        self.costs = list(costs)
        self.succeed_on = succeed_on
        self.tries = 0
        self.ticks = 0

    def initialise(self) -> None:
        self.tries += 1
        self.ticks = 0

    def update(self) -> Status:
        self.ticks += 1
        if self.vehicle.battery is not None:
            self.vehicle.battery -= self.costs[self.tries - 1] / 2
        if self.ticks < 2:
            return Status.RUNNING
        return Status.SUCCESS if self.tries == self.succeed_on else Status.FAILURE


def run(decorator: RetryWhileBattery, max_ticks: int = 200) -> Status:
    for _ in range(max_ticks):
        decorator.tick_once()
        if decorator.status != Status.RUNNING:
            break
    return decorator.status


def failure_reason() -> str | None:
    client = py_trees.blackboard.Client(name="reader")
    client.register_key(key=keys.FAILURE_REASON, access=Access.READ)
    return client.get(keys.FAILURE_REASON)


def make(battery, costs, *, num_failures=20, critical=15.0, attempt_cost=5.0, succeed_on=0):
    keys.initialise()
    vehicle = FakeVehicle(SimClock(), battery=battery)
    child = Try(vehicle, costs, succeed_on)
    decorator = RetryWhileBattery(
        "Landing phase", child, vehicle, num_failures, critical=critical,
        attempt_cost=attempt_cost,
    )
    return decorator, child, vehicle


def test_it_learns_the_largest_drop_and_stops_before_a_try_could_cross_the_critical_level():
    # 40 % -> 37 -> 30 (a 7 % try) -> 28 -> 26 -> 24 -> 22 -> 20: with 7 % learned, a try
    # from 20 % could end at 13 %, under the critical 15 %; the 5 % floor alone would allow it.
    decorator, child, vehicle = make(40.0, [3, 7, 2, 2, 2, 2, 2, 2, 2, 2])

    assert run(decorator) == Status.FAILURE
    assert child.tries == 7
    assert vehicle.battery == pytest.approx(20.0)
    assert decorator.expected_cost == pytest.approx(7.0)
    message = decorator.feedback_message
    assert "battery 20.0 %" in message and "7.0 %" in message and "critical level 15 %" in message
    assert failure_reason() == f"Landing phase: {message}"


def test_the_attempt_cost_floor_holds_until_a_try_costs_more():
    # Tries of 1 %: the 5 % floor decides; a new try needs 20 % or more.
    decorator, child, vehicle = make(24.0, [1] * 10)

    assert run(decorator) == Status.FAILURE
    assert child.tries == 5  # from 24, 23, 22, 21, 20; refused at 19
    assert vehicle.battery == pytest.approx(19.0)
    assert "at least 5 % assumed" in decorator.feedback_message


def test_the_first_try_is_always_allowed():
    decorator, child, _ = make(16.0, [0.5] * 3, attempt_cost=5.0)

    assert run(decorator) == Status.FAILURE
    assert child.tries == 1
    assert "leaves no room for another try" in decorator.feedback_message


def test_an_unknown_battery_behaves_like_retry():
    decorator, child, _ = make(None, [10] * 10, num_failures=4)

    assert run(decorator) == Status.FAILURE
    assert child.tries == 4
    assert "final failure" in decorator.feedback_message


def test_num_failures_still_bounds_the_tries_with_battery_to_spare():
    decorator, child, vehicle = make(100.0, [1] * 10, num_failures=3)

    assert run(decorator) == Status.FAILURE
    assert child.tries == 3
    assert vehicle.battery == pytest.approx(97.0)
    assert "final failure" in decorator.feedback_message


def test_a_successful_try_succeeds():
    decorator, child, _ = make(60.0, [4] * 10, succeed_on=3)

    assert run(decorator) == Status.SUCCESS
    assert child.tries == 3


def test_the_learned_cost_is_kept_when_the_decorator_is_entered_again():
    decorator, child, vehicle = make(100.0, [9, 1, 1, 1, 1, 1], num_failures=1)
    assert run(decorator) == Status.FAILURE  # one 9 % try
    vehicle.battery = 24.5
    decorator.num_failures = 5

    assert run(decorator) == Status.FAILURE
    # Entered again at 24.5 %: the first try is allowed (23.5 % after it); 23.5 - 9 < 15.
    assert child.tries == 2
    assert decorator.expected_cost == pytest.approx(9.0)


@pytest.mark.parametrize(("num_failures", "attempt_cost"), [(0, 5.0), (3, -1.0)])
def test_bad_arguments_are_refused(num_failures, attempt_cost):
    vehicle = FakeVehicle(SimClock())
    with pytest.raises(ValueError):
        RetryWhileBattery("r", py_trees.behaviours.Failure(), vehicle, num_failures, 15.0,
                          attempt_cost)
