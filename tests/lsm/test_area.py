"""The operating area (lsm.area) and the Landing Site Manager's rejections outside it."""

from __future__ import annotations

import numpy as np

from lsm import LandingSiteManager, LsmSettings, OperatingArea, SiteObservation
from lsm.area import NoFlyCircle, self_intersection

# An L: the leg from the east arm to the north arm cuts the missing corner.
L_AREA = OperatingArea(((0, 0), (100, 0), (100, 20), (20, 20), (20, 100), (0, 100)), margin=2)


def _obs(x: float, y: float) -> SiteObservation:
    return SiteObservation(x=x, y=y, z=0.0, roughness=0.1, uncertainty=0.1, size=3.0,
                           obstacle_altitude=0.0, observation_altitude=30.0, timestamp=1.0)


def test_points_inside_keep_the_margin_vectorised():
    inside = L_AREA.contains(np.array([[10, 10], [50, 10], [50, 50], [1, 50], [50, 19]]))
    assert inside.tolist() == [True, True, False, False, False]
    assert L_AREA.contains_point(50, 17.5) and not L_AREA.contains_point(50, 18.5)


def test_a_leg_across_the_missing_corner_leaves_the_area():
    assert not L_AREA.leg_inside((90, 10), (10, 90))
    assert L_AREA.leg_inside((90, 10), (10, 10))
    assert L_AREA.leg_inside((10, 10), (10, 90))
    # Along the edge closer than the margin: out.
    assert not L_AREA.leg_inside((10, 1.0), (90, 1.0))
    # A start the vehicle drifted into the margin from keeps its own clearance.
    assert L_AREA.leg_inside((10, 1.5), (10, 50))


def test_self_intersection_names_the_crossing_edges():
    assert self_intersection([(0, 0), (1, 1), (1, 0), (0, 1)]) == (0, 2)
    assert self_intersection(L_AREA.vertices) is None


def test_the_manager_rejects_sites_outside_and_counts_them():
    lsm = LandingSiteManager(LsmSettings(max_distance=1000))
    assert "rejected_outside_geofence" not in lsm.counters()  # no area, no counter
    lsm.set_area(L_AREA)
    lsm.submit_many([_obs(10, 10), _obs(50, 50), _obs(10, 99.5), _obs(90, 10)])
    lsm.process_pending()
    counters = lsm.counters()
    assert counters["rejected_outside_geofence"] == 2
    assert sorted((s.x, s.y) for s in lsm.ranked((0, 0, 30))) == [(10, 10), (90, 10)]


# A no-fly zone (a building) in the L's east arm.
ZONED = OperatingArea(L_AREA.vertices, margin=2, exclusions=(((40, 5), (60, 5), (60, 15),
                                                               (40, 15)),))


def test_no_fly_zones_are_kept_out_of_with_the_margin():
    points = np.array([[50, 10], [39, 10], [37, 10], [10, 10], [50, 50]])
    assert ZONED.contains(points).tolist() == [False, False, True, True, False]
    assert ZONED.zone_of(points).tolist() == [0, 0, -1, -1, -1]
    # Without zones nothing changes.
    assert L_AREA.contains(points).tolist() == [True, True, True, True, False]


def test_a_leg_across_a_no_fly_zone_is_not_inside():
    assert not ZONED.leg_inside((30, 10), (90, 10))
    assert ZONED.leg_zone((30, 10), (90, 10)) == 0
    assert not ZONED.leg_inside((30, 3.5), (90, 3.5))  # within the margin of its edge
    assert ZONED.leg_inside((30, 10), (10, 10)) and ZONED.leg_zone((30, 10), (10, 10)) is None
    # Leaving the area elsewhere is not the zone's doing.
    assert not ZONED.leg_inside((30, 10), (10, 90)) and ZONED.leg_zone((30, 10), (10, 90)) is None
    # The leg into the zone, and out of it (the vehicle is in it: no way out counts clear).
    assert not ZONED.leg_inside((10, 10), (50, 10))
    assert not ZONED.leg_inside((50, 10), (10, 10))
    # A start the vehicle drifted into the zone's margin from keeps its own clearance.
    assert ZONED.leg_inside((38.5, 10), (10, 10))


def test_the_manager_rejects_sites_in_a_no_fly_zone():
    lsm = LandingSiteManager(LsmSettings(max_distance=1000))
    lsm.set_area(ZONED)
    lsm.submit_many([_obs(50, 10), _obs(61, 10), _obs(80, 10), _obs(10, 10)])
    lsm.process_pending()
    assert lsm.counters()["rejected_outside_geofence"] == 2
    assert sorted((s.x, s.y) for s in lsm.ranked((0, 0, 30))) == [(10, 10), (80, 10)]


def test_a_polygon_overlaps_the_area_in_part_or_whole():
    assert L_AREA.overlaps([(90, 10), (150, 10), (150, 50)])
    assert L_AREA.overlaps([(5, 5), (8, 5), (8, 8)])
    assert not L_AREA.overlaps([(50, 50), (90, 50), (90, 90)])  # the L's missing corner


# A polygon (zone 0) and a circle of radius 5 about (70, 10) (zone 1) in the L's east arm.
CIRCLED = OperatingArea(L_AREA.vertices, margin=2, exclusions=(
    ((40, 2), (60, 2), (60, 18), (40, 18)), NoFlyCircle(70, 10, 5)))


def test_a_no_fly_circle_is_kept_out_of_with_the_margin():
    points = np.array([[70, 10], [74, 10], [76.5, 10], [77.5, 10], [50, 10], [10, 10]])
    assert CIRCLED.contains(points).tolist() == [False, False, False, True, False, True]
    assert CIRCLED.zone_of(points).tolist() == [1, 1, 1, -1, 0, -1]
    assert CIRCLED.edge_distance((78, 10))[0] == np.float64(3.0)
    # Zones are numbered in their order: the circle first here.
    swapped = OperatingArea(L_AREA.vertices, 2, None, CIRCLED.exclusions[::-1])
    assert swapped.zone_of(points).tolist() == [0, 0, 0, -1, 1, -1]


def test_a_leg_passing_a_no_fly_circle_within_its_margin_is_not_inside():
    # Closest approach to (70, 10): 6 m, under radius 5 + margin 2; 8 m is clear.
    assert not CIRCLED.leg_inside((62, 4), (90, 4))
    assert CIRCLED.leg_zone((62, 4), (90, 4)) == 1
    clear = OperatingArea(L_AREA.vertices, 2, None, (NoFlyCircle(70, 12, 5),))
    assert clear.leg_inside((62, 4), (90, 4)) and clear.leg_zone((62, 4), (90, 4)) is None
    # Both ends clear, the middle through the circle: the leg is not.
    assert not clear.leg_inside((62, 12), (90, 12)) and clear.leg_zone((62, 12), (90, 12)) == 0
    # Out of the circle, a start drifted into its margin keeps its own clearance.
    assert clear.leg_inside((70, 5.5), (70, 3))
    assert not clear.leg_inside((70, 14), (90, 14))  # from inside the circle
    # A leg through both zones names the first of them.
    assert CIRCLED.leg_zone((30, 10), (90, 10)) == 0


def test_the_manager_rejects_sites_in_a_no_fly_circle():
    lsm = LandingSiteManager(LsmSettings(max_distance=1000))
    lsm.set_area(OperatingArea(L_AREA.vertices, 2, None, (NoFlyCircle(70, 10, 5),)))
    lsm.submit_many([_obs(70, 10), _obs(75, 12), _obs(80, 10), _obs(10, 10)])
    lsm.process_pending()
    assert lsm.counters()["rejected_outside_geofence"] == 2
    assert sorted((s.x, s.y) for s in lsm.ranked((0, 0, 30))) == [(10, 10), (80, 10)]


def test_a_no_fly_circle_overlaps_the_area_when_it_reaches_in():
    assert L_AREA.overlaps(NoFlyCircle(50, 10, 1))  # inside
    assert L_AREA.overlaps(NoFlyCircle(50, 25, 6))  # centre out, reaching in
    assert not L_AREA.overlaps(NoFlyCircle(50, 50, 20))  # the L's missing corner
    assert L_AREA.overlaps(NoFlyCircle(50, 50, 1000))  # the whole area within
