"""Units of the behaviours package: clear altitude (thesis eq. 3.4-3.5), the clock-aware
timeout, the search geometry, settings validation and the tree renderings."""

from __future__ import annotations

import numpy as np
import py_trees
import pytest
from behaviors_fakes import FakeVehicle
from hypothesis import given
from hypothesis import strategies as st
from py_trees.common import Access, Status
from pydantic import ValidationError

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors import render_ascii, write_dot
from behaviors.decorators import ClockTimeout, RetryWhileBattery
from behaviors.display import dot_text
from behaviors.failsafe import BatteryAllows, BatteryCritical, GpsLost
from behaviors.landing import GetClearAltitude, clear_altitude
from behaviors.search import random_point_in_disc, rectangle_pattern
from behaviors.settings import LandingSettings, MissionPlan
from behaviors.tree import build_mission_tree
from lsm import LandingSite, LandingSiteManager


def site(x=0.0, y=0.0, z=0.0, obstacle_altitude=20.0) -> LandingSite:
    return LandingSite(
        id=1, x=x, y=y, z=z, roughness=0.1, uncertainty=0.1, size=3.0,
        obstacle_altitude=obstacle_altitude, verification_altitude=100.0,
        first_seen=0.0, last_seen=0.0, detection_count=1,
    )  # fmt: skip


def reader() -> py_trees.blackboard.Client:
    client = py_trees.blackboard.Client(name="reader")
    for key in keys.KEYS:
        client.register_key(key=key, access=Access.READ)
    return client


# ---------------------------------------------------------------- clear altitude


def test_clear_altitude_adds_buffer_and_horizontal_distance_to_the_obstacle_altitude():
    # Drone 30 m away horizontally (a 3-4-5 triangle), 80 m up: the height does not count.
    z = clear_altitude(site(10, 10, obstacle_altitude=20), (28, 34, 80), 10.0, 500.0)
    assert z == pytest.approx(20 + 10 + 30)


def test_clear_altitude_is_capped_at_the_failsafe_altitude():
    far = clear_altitude(site(obstacle_altitude=20), (1000, 0, 50), 10.0, 120.0)
    assert far == 120.0


def test_clear_altitude_grows_with_distance_until_the_cap():
    values = [clear_altitude(site(), (d, 0, 0), 5.0, 100.0) for d in range(0, 200, 10)]
    assert values == sorted(values)
    assert values[0] == 25.0 and values[-1] == 100.0


@given(
    obstacle=st.floats(-50, 200),
    buffer=st.floats(0, 50),
    cap=st.floats(1, 300),
    dx=st.floats(-500, 500),
    dy=st.floats(-500, 500),
)
def test_clear_altitude_never_exceeds_the_cap_and_clears_the_obstacle_when_it_can(
    obstacle, buffer, cap, dx, dy
):
    z = clear_altitude(site(obstacle_altitude=obstacle), (dx, dy, 0.0), buffer, cap)
    assert z <= cap
    assert z >= min(obstacle + buffer, cap)
    closer = clear_altitude(site(obstacle_altitude=obstacle), (dx / 2, dy / 2, 0.0), buffer, cap)
    assert closer <= z + 1e-9


def test_get_clear_altitude_behaviour_writes_the_blackboard():
    keys.initialise()
    clock = SimClock()
    vehicle = FakeVehicle(clock)
    vehicle.position = (40.0, 0.0, 60.0)
    writer = py_trees.blackboard.Client(name="writer")
    writer.register_key(key=keys.LANDING_SITE, access=Access.WRITE)
    node = GetClearAltitude("GetClearAltitude", vehicle, buffer=10.0, failsafe_altitude=120.0)

    node.tick_once()
    assert node.status == Status.FAILURE  # no site chosen yet
    assert "no landing site" in reader().get(keys.FAILURE_REASON)

    writer.set(keys.LANDING_SITE, site(10, 0, obstacle_altitude=20))
    node.tick_once()
    assert node.status == Status.SUCCESS
    assert reader().get(keys.CLEAR_ALTITUDE) == pytest.approx(20 + 10 + 30)


# ---------------------------------------------------------------- clock timeout


def test_clock_timeout_fails_a_running_child_after_the_duration_of_clock_time():
    keys.initialise()
    clock = SimClock()
    child = py_trees.behaviours.Running(name="Hover")
    timeout = ClockTimeout("Hover within 10 s", child, clock, 10.0)

    for _ in range(5):
        timeout.tick_once()  # no clock advance: wall time passing changes nothing
    assert timeout.status == Status.RUNNING
    clock.advance(9.5)
    timeout.tick_once()
    assert timeout.status == Status.RUNNING
    clock.advance(0.5)
    timeout.tick_once()
    assert timeout.status == Status.FAILURE
    assert child.status == Status.INVALID
    assert "timed out after 10 s" in timeout.feedback_message
    assert reader().get(keys.FAILURE_REASON).startswith("Hover: timed out after 10 s")


def test_clock_timeout_passes_through_a_finished_child_and_restarts_on_reentry():
    keys.initialise()
    clock = SimClock()
    child = py_trees.behaviours.StatusQueue(
        name="Two then done",
        queue=[Status.RUNNING, Status.RUNNING, Status.SUCCESS],
        eventually=Status.RUNNING,
    )
    timeout = ClockTimeout("within 5 s", child, clock, 5.0)
    statuses = []
    for _ in range(3):
        clock.advance(2.0)
        timeout.tick_once()
        statuses.append(timeout.status)
    assert statuses == [Status.RUNNING, Status.RUNNING, Status.SUCCESS]
    # Entered again: a fresh 5 s from now, not from the first entry.
    timeout.tick_once()
    clock.advance(4.0)
    timeout.tick_once()
    assert timeout.status == Status.RUNNING


def test_clock_timeout_rejects_a_non_positive_duration():
    with pytest.raises(ValueError, match="duration"):
        ClockTimeout("t", py_trees.behaviours.Running(), SimClock(), 0.0)


# ---------------------------------------------------------------- search geometry


def test_rectangle_pattern_is_closed_around_the_centre_and_starts_at_the_nearest_corner():
    corners = rectangle_pattern((100.0, 50.0), (60.0, 40.0), 80.0, start_near=(140.0, 80.0))
    assert corners[0] == corners[-1] == (130.0, 70.0, 80.0)
    assert len(corners) == 5
    xs = sorted({c[0] for c in corners})
    ys = sorted({c[1] for c in corners})
    assert xs == [70.0, 130.0] and ys == [30.0, 70.0]


def test_random_pattern_centres_are_seeded_and_inside_the_radius():
    a = [random_point_in_disc(np.random.default_rng(7), (5.0, -3.0), 50.0) for _ in range(2)]
    assert a[0] == a[1]
    rng = np.random.default_rng(1)
    points = np.array([random_point_in_disc(rng, (5.0, -3.0), 50.0) for _ in range(2000)])
    r = np.hypot(points[:, 0] - 5.0, points[:, 1] + 3.0)
    assert r.max() <= 50.0
    # Uniform over the disc: about a quarter of the points inside half the radius.
    assert 0.2 < np.mean(r <= 25.0) < 0.3


# ---------------------------------------------------------------- settings


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"verification_altitude": 0}, "verification_altitude"),
        ({"battery_critical": 40, "battery_reserve": 30}, "battery_critical"),
        ({"search_rectangle": (60, 0)}, "search_rectangle"),
        ({"landing_retries": 0}, "landing_retries"),
        ({"landing_try_battery": -1}, "landing_try_battery"),
        ({"verification_duration": float("nan")}, "verification_duration"),
        ({"unknown_field": 1}, "unknown_field"),
    ],
)
def test_bad_landing_settings_name_the_field(kwargs, field):
    with pytest.raises(ValidationError, match=field):
        LandingSettings(**kwargs)


def test_mission_plan_needs_waypoints_above_home():
    with pytest.raises(ValidationError, match="waypoints"):
        MissionPlan(waypoints=[])
    with pytest.raises(ValidationError, match=r"waypoints\.1\.2"):
        MissionPlan(waypoints=[(0, 0, 50), (10, 0, -5)])
    with pytest.raises(ValidationError, match=r"waypoints\[1\]: 60000 m from home"):
        MissionPlan(waypoints=[(0, 0, 50), (36_000, 48_000, 50)])
    plan = MissionPlan(waypoints=[(0, 0, 50), (10, 0, 70)])
    assert plan.effective_takeoff_altitude == 50
    assert MissionPlan(waypoints=[(0, 0, 50)], takeoff_altitude=20).effective_takeoff_altitude == 20


# ---------------------------------------------------------------- renderings and keys


def build() -> py_trees.trees.BehaviourTree:
    clock = SimClock()
    return build_mission_tree(
        MissionPlan(waypoints=[(0, 0, 50), (30, 0, 50)]),
        FakeVehicle(clock),
        LandingSiteManager(),
        clock,
        np.random.default_rng(0),
    )


def test_build_writes_every_key_start_value():
    keys.reset()
    build()
    assert {key: reader().get(key) for key in keys.KEYS} == dict(keys.DEFAULTS)
    keys.reset()
    assert all(value is None for value in keys.read_all().values())


def test_retry_counts_come_from_the_landing_settings():
    clock = SimClock()
    plan = MissionPlan(
        waypoints=[(0, 0, 50)], landing=LandingSettings(landing_retries=4, pattern_retries=2)
    )
    tree = build_mission_tree(
        plan, FakeVehicle(clock), LandingSiteManager(), clock, np.random.default_rng(0)
    )
    retries = {
        node.name: node.num_failures
        for node in tree.root.iterate()
        if isinstance(node, py_trees.decorators.Retry)
    }
    assert retries == {"Landing phase": 4, "Pattern retries": 2}


def test_the_landing_phase_is_bounded_by_the_critical_level_and_the_try_cost_setting():
    clock = SimClock()
    landing = LandingSettings(battery_critical=12, landing_try_battery=7.5)
    tree = build_mission_tree(
        MissionPlan(waypoints=[(0, 0, 50)], landing=landing), FakeVehicle(clock),
        LandingSiteManager(), clock, np.random.default_rng(0),
    )
    phase, = (n for n in tree.root.iterate() if isinstance(n, RetryWhileBattery))
    assert (phase.name, phase.critical, phase.attempt_cost) == ("Landing phase", 12, 7.5)


@pytest.mark.parametrize(
    "battery, cost, status",
    [(30.0, 10.0, Status.SUCCESS), (24.0, 10.0, Status.FAILURE), (None, 90.0, Status.SUCCESS)],
)
def test_battery_allows_a_flight_only_above_the_critical_level(battery, cost, status):
    # Critical 15 %: 30 - 10 stays above it, 24 - 10 would not; an unknown level does not guard.
    vehicle = FakeVehicle(SimClock(), battery=battery)
    guard = BatteryAllows("guard", vehicle, critical=15.0, cost=lambda: cost)
    guard.tick_once()
    assert guard.status == status


def test_every_failsafe_writes_a_kind_the_reports_know():
    assert {BatteryCritical.kind, GpsLost.kind} == set(keys.FAILSAFE_KINDS)


def test_render_ascii_and_write_dot_show_every_node(tmp_path):
    tree = build()
    names = [node.name for node in tree.root.iterate()]
    text = render_ascii(tree)
    assert all(name in text for name in names)
    path = write_dot(tree, tmp_path / "mission.dot")
    dot = (tmp_path / "mission.dot").read_text()
    assert path == str(tmp_path / "mission.dot")
    assert dot.startswith("digraph") and dot.rstrip().endswith("}")
    assert dot.count("->") == len(names) - 1  # a tree: one edge per non-root node
    for name in ("LandingSiteVerification", "Battery critical?", "Pattern retries"):
        assert f'label="{name}\\n' in dot


def test_dot_text_colours_nodes_by_status():
    tree = build()
    tree.tick()
    assert "penwidth" not in dot_text(tree)
    assert "color=blue" in dot_text(tree, show_status=True)  # the running branch


def test_node_names_in_dot_are_escaped():
    node = py_trees.behaviours.Success(name='say "hi"')
    assert 'label="say \\"hi\\"\\n' in dot_text(node)
