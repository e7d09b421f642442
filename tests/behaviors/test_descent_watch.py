"""WatchedDescent: the descent to the verification altitude that steps away from obstacles
the optical flow flags (seed 004), on the fake vehicle."""

from __future__ import annotations

import math

import py_trees
import pytest
from behaviors_fakes import FakeVehicle
from py_trees.common import Status

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.descent_watch import WatchedDescent, away_in_enu, step_within
from behaviors.ports import ObstacleSighting
from lsm.records import LandingSite

SITE = LandingSite(id=1, x=10.0, y=5.0, z=1.0, roughness=0.0, uncertainty=0.0, size=3.0,
                   obstacle_altitude=1.0, verification_altitude=20.0, first_seen=0.0,
                   last_seen=0.0, detection_count=1)


class FakeWatch:
    """Flags an obstacle to the image's right (away: image left) whenever the vehicle is
    within ``band`` (z range) and watching is on; records every on/off."""

    def __init__(self, clock, vehicle, band=(0.0, -1.0), yaw=0.0):
        self.clock, self.vehicle, self.band, self.yaw = clock, vehicle, band, yaw
        self.on = False
        self.calls: list[bool] = []

    def watch(self, on: bool) -> None:
        self.on = on
        self.calls.append(on)

    def latest(self):
        if not self.on:
            return None
        z = self.vehicle.position[2]
        flagged = self.band[0] <= z <= self.band[1]
        return ObstacleSighting(time=self.clock.now(), obstacle=flagged,
                                away=(-1.0, 0.0) if flagged else (0.0, 0.0), yaw=self.yaw,
                                directions=("right",) if flagged else ())


def _run(vehicle, clock, behaviour, max_time=120.0):
    bb = py_trees.blackboard.Client(name="test")
    bb.register_key(key=keys.LANDING_SITE, access=py_trees.common.Access.WRITE)
    keys.initialise()
    bb.set(keys.LANDING_SITE, SITE)
    behaviour.setup_with_descendants()
    track = []
    status = Status.RUNNING
    while clock.now() < max_time:
        clock.advance(0.1)
        vehicle.step(0.1)
        track.append(vehicle.position)
        behaviour.tick_once()
        status = behaviour.status
        if status != Status.RUNNING:
            break
    return status, track


def _airborne(clock, start=(10.0, 5.0, 21.0)):
    vehicle = FakeVehicle(clock, speed=3.0, climb_rate=1.5)
    vehicle.armed = True
    vehicle.position = start
    return vehicle


def test_without_sightings_it_descends_straight_over_the_site():
    clock = SimClock()
    vehicle = _airborne(clock)
    watch = FakeWatch(clock, vehicle)
    descent = WatchedDescent("Descend", vehicle, clock, 2.5, watch)
    status, track = _run(vehicle, clock, descent)
    assert status is Status.SUCCESS
    assert vehicle.gotos() == [(10.0, 5.0, 3.5)]
    assert max(math.hypot(x - 10.0, y - 5.0) for x, y, _ in track) < 1e-9
    assert watch.calls[0] is True and watch.calls[-1] is False  # on while descending only


def test_an_obstacle_on_the_right_stops_the_descent_and_steps_left_then_resumes():
    clock = SimClock()
    vehicle = _airborne(clock)
    # Flagged between 15 and 16 m; heading east, so image right is south: step north.
    watch = FakeWatch(clock, vehicle, band=(15.0, 16.0), yaw=0.0)
    descent = WatchedDescent("Descend", vehicle, clock, 2.5, watch, step=1.5, max_offset=3.0,
                             settle=0.5)
    status, track = _run(vehicle, clock, descent)
    assert status is Status.SUCCESS
    gotos = vehicle.gotos()
    assert gotos[0] == (10.0, 5.0, 3.5)
    stop = gotos[1]  # the descent stops where it was, 1.5 m north of the column
    assert 15.0 <= stop[2] <= 16.0 and stop[:2] == pytest.approx((10.0, 6.5))
    assert gotos[2] == pytest.approx((10.0, 6.5, 3.5))  # and resumes over the new column
    # Still flagged in the band after resuming: the second step reaches the 3 m bound.
    assert max(abs(x - 10.0) for x, _, _ in track) < 1e-6
    assert max(y for _, y, _ in track) == pytest.approx(8.0)
    assert vehicle.position[:2] == pytest.approx((10.0, 8.0))
    assert vehicle.position[2] == pytest.approx(3.5, abs=1.0)  # the acceptance radius
    assert watch.calls[-1] is False


def test_with_no_room_left_it_climbs_back_and_fails_with_the_reason():
    clock = SimClock()
    vehicle = _airborne(clock)
    watch = FakeWatch(clock, vehicle, band=(8.0, 16.0), yaw=0.0)
    descent = WatchedDescent("Descend", vehicle, clock, 2.5, watch, step=1.5, max_offset=2.0,
                             settle=0.5)
    status, track = _run(vehicle, clock, descent)
    assert status is Status.FAILURE
    assert "no room to step away within 2 m" in descent.feedback_message
    assert vehicle.position[2] == pytest.approx(21.0, abs=1.0)  # back where it began
    assert max(math.hypot(x - 10.0, y - 5.0) for x, y, _ in track) <= 2.0 + 1e-6
    assert min(z for _, _, z in track) > 8.0 - 1.0  # never below the flagged band


def test_sightings_right_after_a_step_do_not_count():
    clock = SimClock()
    vehicle = _airborne(clock)
    watch = FakeWatch(clock, vehicle, band=(15.0, 16.0), yaw=0.0)
    # The vehicle descends through the band in under a second: settle covers it.
    descent = WatchedDescent("Descend", vehicle, clock, 2.5, watch, step=1.5, max_offset=3.0,
                             settle=5.0)
    status, _ = _run(vehicle, clock, descent)
    assert status is Status.SUCCESS and len(vehicle.gotos()) == 1  # first one within settle


def test_a_denied_goto_fails_the_descent_and_stops_the_watch():
    clock = SimClock()
    vehicle = _airborne(clock)
    vehicle.deny["goto"] = "Mode change denied"
    watch = FakeWatch(clock, vehicle)
    status, _ = _run(vehicle, clock, WatchedDescent("Descend", vehicle, clock, 2.5, watch))
    assert status is Status.FAILURE and watch.calls[-1] is False


@pytest.mark.parametrize(
    ("away", "yaw", "enu"),
    [((0.0, 1.0), 0.0, (1.0, 0.0)),  # image up is the nose: east at yaw 0
     ((1.0, 0.0), 0.0, (0.0, -1.0)),  # image right is the vehicle's right: south
     ((0.0, 1.0), math.pi / 2, (0.0, 1.0)),  # heading north
     ((1.0, 0.0), math.pi / 2, (1.0, 0.0))],  # its right is east
)
def test_image_directions_turn_into_enu_with_the_heading(away, yaw, enu):
    assert away_in_enu(away, yaw) == pytest.approx(enu, abs=1e-12)


def test_a_step_stops_at_the_offset_bound():
    assert step_within((0.0, 0.0), (1.0, 0.0), 1.5, 3.0) == pytest.approx(1.5)
    assert step_within((2.0, 0.0), (1.0, 0.0), 1.5, 3.0) == pytest.approx(1.0)
    assert step_within((3.0, 0.0), (1.0, 0.0), 1.5, 3.0) == pytest.approx(0.0)
    assert step_within((3.0, 0.0), (-1.0, 0.0), 1.5, 3.0) == pytest.approx(1.5)


class CarUnderVehicle(FakeVehicle):
    """The fake vehicle with a downward rangefinder; from ``car_from`` s on, a 1.6 m car
    stands under it wherever it is."""

    def __init__(self, clock, car_from, **kwargs):
        super().__init__(clock, **kwargs)
        self.car_from = car_from

    @property
    def state(self):
        import dataclasses

        state = super().state
        top = 1.6 if self.clock.now() >= self.car_from else 0.0
        return dataclasses.replace(state, rangefinder_agl=self.position[2] - top)


class BanningLsm:
    def __init__(self):
        self.banned = []

    def ban(self, site_id):
        self.banned.append(site_id)
        return True


def test_a_car_under_the_column_makes_it_climb_back_and_ban_the_site():
    from behaviors.descent_watch import WatchAborts

    aborts, lsm = WatchAborts(), BanningLsm()
    for attempt, ban_after in ((1, 2), (2, 2)):
        clock = SimClock()
        vehicle = CarUnderVehicle(clock, car_from=5.0, speed=3.0, climb_rate=1.5)
        vehicle.armed, vehicle.position = True, (10.0, 5.0, 21.0)
        descent = WatchedDescent("Descend", vehicle, clock, 2.5, FakeWatch(clock, vehicle),
                                 column_margin=0.5, lsm=lsm, aborts=aborts,
                                 ban_after=ban_after)
        status, track = _run(vehicle, clock, descent)
        assert status is Status.FAILURE
        assert "1.6 m high entered the column below" in descent.feedback_message
        assert vehicle.position[2] == pytest.approx(21.0, abs=1.0)  # back where it began
        assert min(z for _, _, z in track) > 21.0 - 1.5 * 5.0 - 1.0  # stopped at once
        if attempt == 1:  # the first retreat keeps the site for another try
            assert "site 1 kept (1 retreat(s), banned after 2)" in descent.feedback_message
            assert lsm.banned == []
        else:
            assert descent.feedback_message.endswith("(site 1 banned)")
            assert lsm.banned == [1]
