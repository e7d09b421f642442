"""Search behaviours inside an operating area: rectangles shrink to fit, pattern centres
are redrawn inside, and a centre that cannot be placed is a failure, not a loop."""

from __future__ import annotations

import numpy as np
import py_trees
from behaviors_fakes import FakeVehicle
from py_trees.common import Status

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.landing import GetLandingSite
from behaviors.search import CENTRE_DRAWS, GetNextPatternCenterWP, LandingSiteSearch
from lsm import LandingSiteManager, LsmSettings, OperatingArea, SiteObservation

SQUARE = OperatingArea(((0, 0), (50, 0), (50, 50), (0, 50)), margin=2.0)


def _vehicle(position):
    clock = SimClock()
    vehicle = FakeVehicle(clock)
    vehicle.armed, vehicle.position = True, position
    return clock, vehicle


class _CountingRng:
    def __init__(self, seed):
        self.rng, self.draws = np.random.default_rng(seed), 0

    def random(self):
        self.draws += 1
        return self.rng.random()


def test_a_pattern_centre_that_cannot_be_placed_fails_after_a_bounded_number_of_draws():
    clock, vehicle = _vehicle((25.0, 25.0, 30.0))
    rng = _CountingRng(0)
    node = GetNextPatternCenterWP("centre", vehicle, clock, rng, anchor=(500.0, 500.0),
                                  radius=20.0, altitude=30.0, area=SQUARE)
    tree = py_trees.trees.BehaviourTree(node)
    tree.tick()
    assert node.status is Status.FAILURE
    assert "no pattern centre inside the geofence" in node.feedback_message
    assert rng.draws == 2 * CENTRE_DRAWS  # two numbers a draw


def test_pattern_centres_are_drawn_inside():
    clock, vehicle = _vehicle((25.0, 25.0, 30.0))
    node = GetNextPatternCenterWP("centre", vehicle, clock, np.random.default_rng(3),
                                  anchor=(48.0, 48.0), radius=40.0, altitude=30.0,
                                  area=SQUARE)
    tree = py_trees.trees.BehaviourTree(node)
    for _ in range(20):
        tree.tick()
        assert node.center is not None and SQUARE.contains_point(*node.center)
        node.stop(Status.INVALID)


def test_a_search_rectangle_near_the_edge_shrinks_to_fit():
    clock, vehicle = _vehicle((40.0, 40.0, 30.0))
    search = LandingSiteSearch("search", vehicle, clock, LandingSiteManager(LsmSettings()),
                               size=(40.0, 30.0), altitude=30.0, area=SQUARE)
    writer = py_trees.blackboard.Client(name="test")
    writer.register_key(key=keys.SEARCH_PATTERNS, access=py_trees.common.Access.WRITE)
    writer.set(keys.SEARCH_PATTERNS, 0)
    route = search.plan_route((40.0, 40.0, 30.0))
    assert not isinstance(route, str)
    assert SQUARE.contains(np.array(route)[:, :2]).all()
    assert SQUARE.route_inside([(40.0, 40.0), *route])


# The square with a no-fly zone (a building) across its east side and one in the middle.
ZONED = OperatingArea(SQUARE.vertices, margin=2.0,
                      exclusions=(((40, 20), (48, 20), (48, 30), (40, 30)),
                                  ((20, 20), (30, 20), (30, 30), (20, 30))))


def test_a_search_rectangle_across_a_no_fly_zone_shrinks_to_keep_out():
    clock, vehicle = _vehicle((25.0, 10.0, 30.0))
    writer = py_trees.blackboard.Client(name="test")
    writer.register_key(key=keys.SEARCH_PATTERNS, access=py_trees.common.Access.WRITE)
    writer.set(keys.SEARCH_PATTERNS, 0)
    full = LandingSiteSearch("search", vehicle, clock, LandingSiteManager(LsmSettings()),
                             size=(40.0, 30.0), altitude=30.0, area=SQUARE)
    assert len(full.plan_route((25.0, 10.0, 30.0))) == 5  # fits the square as it is
    search = LandingSiteSearch("search", vehicle, clock, LandingSiteManager(LsmSettings()),
                               size=(40.0, 30.0), altitude=30.0, area=ZONED)
    route = search.plan_route((25.0, 10.0, 30.0))
    assert not isinstance(route, str)
    assert ZONED.route_inside([(25.0, 10.0), *route])
    assert max(x for x, _, _ in route) < 38  # the east side stays off the building


def test_pattern_centres_are_drawn_outside_the_no_fly_zones():
    clock, vehicle = _vehicle((5.0, 5.0, 30.0))
    node = GetNextPatternCenterWP("centre", vehicle, clock, np.random.default_rng(3),
                                  anchor=(25.0, 25.0), radius=10.0, altitude=30.0,
                                  area=ZONED)
    tree = py_trees.trees.BehaviourTree(node)
    for _ in range(20):
        tree.tick()
        assert node.center is not None and (ZONED.zone_of(node.center) == -1).all()
        assert ZONED.leg_inside((5.0, 5.0), node.center)
        node.stop(Status.INVALID)


def test_the_best_site_behind_a_no_fly_zone_is_passed_over():
    keys.initialise()
    clock, vehicle = _vehicle((25.0, 5.0, 30.0))
    lsm = LandingSiteManager(LsmSettings())
    lsm.set_area(ZONED)
    lsm.submit_many([
        SiteObservation(x=25.0, y=40.0, z=0.0, roughness=0.0, uncertainty=0.0, size=5.0,
                        obstacle_altitude=0.0, observation_altitude=30.0, timestamp=1.0),
        SiteObservation(x=8.0, y=40.0, z=0.0, roughness=0.8, uncertainty=0.5, size=1.0,
                        obstacle_altitude=0.0, observation_altitude=30.0, timestamp=1.0)])
    lsm.process_pending()
    assert [(s.x, s.y) for s in lsm.ranked((25.0, 5.0, 30.0))][0] == (25.0, 40.0)
    node = GetLandingSite("site", vehicle, lsm, buffer=10.0, failsafe_altitude=120.0,
                          area=ZONED)
    node.tick_once()
    assert node.status is Status.SUCCESS
    reader = py_trees.blackboard.Client(name="reader")
    reader.register_key(key=keys.LANDING_SITE, access=py_trees.common.Access.READ)
    site = reader.get(keys.LANDING_SITE)
    assert (site.x, site.y) == (8.0, 40.0)  # the leg to (25, 40) crosses the middle zone
