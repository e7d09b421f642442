"""The full mission tree, ticked in lockstep with a fake vehicle and the real LSM: one test
per branch of DESIGN.md section 5."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import py_trees
import pytest
from behaviors_fakes import FakeVehicle, Flight, ScriptedDetector, ScriptedSite, fly
from py_trees.common import Access, Status

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.landing import clear_altitude
from behaviors.search import random_point_in_disc
from behaviors.settings import LandingSettings, MissionPlan
from behaviors.tree import build_mission_tree
from lsm import LandingSiteManager, LsmSettings


@dataclass
class Mission:
    plan: MissionPlan
    clock: SimClock
    vehicle: FakeVehicle
    lsm: LandingSiteManager
    detector: ScriptedDetector
    tree: py_trees.trees.BehaviourTree
    board: py_trees.blackboard.Client

    def fly(self, **kwargs) -> Flight:
        return fly(self.tree, self.vehicle, self.clock, self.lsm, self.detector, **kwargs)

    def read(self, key: str):
        return self.board.get(key)


def make_mission(
    waypoints,
    sites=(),
    *,
    landing: dict | None = None,
    vehicle: dict | None = None,
    footprint: float = 0.3,
    seed: int = 0,
) -> Mission:
    plan = MissionPlan(waypoints=list(waypoints), landing=LandingSettings(**(landing or {})))
    clock = SimClock()
    fake = FakeVehicle(clock, **(vehicle or {}))
    lsm = LandingSiteManager(LsmSettings(max_distance=150.0))
    detector = ScriptedDetector(list(sites), footprint=footprint)
    tree = build_mission_tree(plan, fake, lsm, clock, np.random.default_rng(seed))
    board = py_trees.blackboard.Client(name="test runner")
    for key in keys.KEYS:
        board.register_key(key=key, access=Access.READ)
    return Mission(plan, clock, fake, lsm, detector, tree, board)


def xy_distance(a, b) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


def assert_landed_at(m: Mission, flight: Flight, site: ScriptedSite) -> None:
    assert flight.status == Status.SUCCESS
    assert m.read(keys.PHASE) == "done"
    assert not m.vehicle.armed
    assert m.vehicle.position[2] == pytest.approx(site.z, abs=0.06)
    assert xy_distance(m.vehicle.position, (site.x, site.y)) <= m.plan.landing.acceptance_radius


def test_lands_on_the_verified_position_not_the_high_altitude_estimate():
    # Seen from 100 m the site appears 0.8 m east of where it is; the low look that
    # verifies it moves the record, and the vehicle centres over it before landing.
    site = ScriptedSite(120.0, 10.0, high_offset=(0.8, 0.0))
    m = make_mission([(0, 0, 100), (150, 0, 100)], [site])
    phases: list[str] = []

    flight = m.fly(on_tick=lambda _: phases.append(m.read(keys.PHASE)))
    phases.append(m.read(keys.PHASE))

    assert flight.status == Status.SUCCESS
    assert xy_distance(m.vehicle.position, (site.x, site.y)) <= m.plan.landing.centring_radius
    order = [p for k, p in enumerate(phases) if k == 0 or p != phases[k - 1]]
    assert order[-3:] == ["verification", "land", "done"] or order[-4:] == [
        "verification", "centre", "land", "done"]  # the display names the centring step


def test_verification_hover_follows_the_site_as_lower_looks_move_it():
    # From 10 m up the site appears 1.8 m east of where it is; the camera sees it only
    # within 1 m of the nadir at 2.5 m. The look on the way down moves the record to the
    # true position; the hover must follow it there to re-detect the site from 2.5 m.
    site = ScriptedSite(120.0, 10.0, high_offset=(1.8, 0.0))
    m = make_mission([(0, 0, 100), (150, 0, 100)], [site])

    flight = m.fly()

    assert_landed_at(m, flight, site)
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 1
    assert m.read(keys.BANNED_SITES) == 0
    # The hover went to 2.5 m above the site's true position.
    assert (site.x, site.y, site.z + 2.5) in [
        tuple(round(v, 6) for v in g) for g in m.vehicle.gotos()]


def test_nominal_mission_lands_at_the_best_verified_site():
    good = ScriptedSite(120.0, 10.0, roughness=0.05)
    poor = ScriptedSite(60.0, -15.0, roughness=0.7, size=1.0)
    m = make_mission([(0, 0, 100), (150, 0, 100)], [good, poor])

    flight = m.fly()

    assert_landed_at(m, flight, good)
    chosen = m.read(keys.LANDING_SITE)
    assert (chosen.x, chosen.y) == (good.x, good.y)
    assert m.lsm.is_verified(chosen)
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 1
    assert m.read(keys.OUTCOME_HINT) is None
    assert m.read(keys.FAILURE_REASON) is None
    # Takeoff reached the first waypoint; the second was flown before the landing phase.
    assert m.vehicle.gotos()[0] == (150.0, 0.0, 100.0)


def test_failed_verification_bans_the_site_and_lands_at_the_next_one():
    false_positive = ScriptedSite(120.0, 10.0, roughness=0.05, fails_verification=True)
    second = ScriptedSite(80.0, -20.0, roughness=0.3, obstacle_altitude=12.0)
    m = make_mission([(0, 0, 100), (150, 0, 100)], [false_positive, second])

    flight = m.fly()

    assert_landed_at(m, flight, second)
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 2
    assert m.read(keys.BANNED_SITES) == 1
    assert m.read(keys.FAILURE_REASON) is None  # recovered from: not a failed mission
    assert m.lsm.counters()["banned"] == 1
    (bx, by, _), = m.lsm.ban_zones()
    assert (bx, by) == (false_positive.x, false_positive.y)
    assert all(xy_distance(s.position, (bx, by)) > 1 for s in m.lsm.ranked())
    # From the low verification hover it climbs to the clear altitude before moving sideways.
    z_clear = clear_altitude(
        m.read(keys.LANDING_SITE),
        (false_positive.x, false_positive.y),
        m.plan.landing.clear_altitude_buffer,
        m.plan.landing.failsafe_altitude,
    )
    low = next(
        i
        for i, p in enumerate(flight.track)
        if p[2] < false_positive.z + 3.6
        and xy_distance(p, (false_positive.x, false_positive.y)) < 1.0
    )
    for p in flight.track[low:]:
        away_from_both = (
            xy_distance(p, (false_positive.x, false_positive.y)) > 1.5
            and xy_distance(p, (second.x, second.y)) > 1.5
        )
        if away_from_both:
            assert p[2] >= z_clear - m.plan.landing.acceptance_radius


def test_without_verification_it_lands_on_the_false_positive():
    # The comparison case of the thesis procedure: with landing.verify off nothing checks the
    # site from low altitude, so the false positive is landed on.
    false_positive = ScriptedSite(120.0, 10.0, roughness=0.05, fails_verification=True)
    second = ScriptedSite(80.0, -20.0, roughness=0.3, obstacle_altitude=12.0)
    m = make_mission([(0, 0, 100), (150, 0, 100)], [false_positive, second],
                     landing={"verify": False})

    flight = m.fly()

    assert_landed_at(m, flight, false_positive)
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 0
    assert m.lsm.counters()["banned"] == 0


def test_no_site_known_search_pattern_finds_one():
    # 50 m east of the last waypoint: out of the 30 m footprint during the mission, inside
    # it from the search rectangle's east side.
    hidden = ScriptedSite(150.0, 0.0)
    m = make_mission([(0, 0, 100), (100, 0, 100)], [hidden])

    flight = m.fly()

    assert_landed_at(m, flight, hidden)
    assert m.read(keys.SEARCH_PATTERNS) == 1
    assert m.read(keys.PATTERN_CENTER) is None


def _distance_to_segment(p, a, b) -> float:
    a, b, p = np.asarray(a, float), np.asarray(b, float), np.asarray(p, float)
    t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
    return float(np.linalg.norm(p - (a + t * (b - a))))


def test_empty_search_moves_to_a_new_pattern_centre_and_finds_a_site_there():
    last = (100.0, 0.0)
    radius = 100.0
    # A seed whose first new centre lies beyond what the mission and the first pattern see.
    seed = next(
        s
        for s in range(1000)
        if xy_distance(random_point_in_disc(np.random.default_rng(s), last, radius), last) > 60
        and _distance_to_segment(
            random_point_in_disc(np.random.default_rng(s), last, radius), (0, 0), last
        )
        > 30
    )
    center = random_point_in_disc(np.random.default_rng(seed), last, radius)
    site = ScriptedSite(*center)
    m = make_mission(
        [(0, 0, 100), (*last, 100)],
        [site],
        landing={"pattern_center_radius": radius, "search_rectangle": (40.0, 30.0)},
        footprint=0.15,
        seed=seed,
    )

    flight = m.fly()

    assert_landed_at(m, flight, site)
    # One empty pattern; the site was seen on arriving at the new centre, so the second
    # pattern had nothing left to do.
    assert m.read(keys.SEARCH_PATTERNS) == 1
    assert m.read(keys.PATTERN_CENTER) == pytest.approx(center)
    assert m.vehicle.gotos().count((*center, m.plan.cruise_altitude)) == 1


def test_every_landing_retry_exhausted_lands_in_place_with_no_site_hint():
    landing = {
        "landing_retries": 2,
        "pattern_retries": 1,
        "search_rectangle": (20.0, 20.0),
        "pattern_center_radius": 30.0,
    }
    m = make_mission([(0, 0, 60), (50, 0, 60)], [], landing=landing)

    flight = m.fly()

    assert flight.status == Status.SUCCESS
    assert m.read(keys.OUTCOME_HINT) == "no_site"
    assert m.read(keys.PHASE) == "done"
    assert m.read(keys.SEARCH_PATTERNS) == 2 * (1 + 1)
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 0
    assert not m.vehicle.armed and m.vehicle.position[2] == pytest.approx(0.0, abs=0.06)
    # It landed where it was: straight down from where the last pattern ended.
    assert m.vehicle.commands[-1][0] == "land"
    assert xy_distance(m.vehicle.position, m.vehicle.gotos()[-1]) <= 1.0


def test_with_the_tries_spent_it_lands_on_a_site_verified_beside_the_last_one():
    # One landing try. The hover over the chosen false positive also sees, from low
    # altitude, a rougher site 4 m away (a wide footprint): it is verified but never tried.
    # With the try spent, landing in place would come down on the ground that just failed
    # verification; it lands on the verified site instead.
    false_positive = ScriptedSite(120.0, 10.0, roughness=0.05, fails_verification=True)
    beside = ScriptedSite(124.0, 10.0, roughness=0.5)
    m = make_mission([(0, 0, 100), (150, 0, 100)], [false_positive, beside],
                     landing={"landing_retries": 1}, footprint=2.0)

    flight = m.fly()

    assert_landed_at(m, flight, beside)
    assert m.read(keys.OUTCOME_HINT) == "verified_site"
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 1  # no second hover
    assert m.read(keys.BANNED_SITES) == 1
    assert m.read(keys.LANDING_SITE).x == beside.x
    assert xy_distance(m.vehicle.position, (beside.x, beside.y)) <= m.plan.landing.centring_radius


def test_a_verified_site_is_not_flown_to_when_the_battery_leaves_no_room():
    # The flight of the test above from 26.5 %, each try costing 6 %: after the one try the
    # battery is at 20.5 %, and another 6 % could end under the critical 15 %, so it lands in
    # place although a verified site is 4 m away.
    false_positive = ScriptedSite(120.0, 10.0, roughness=0.05, fails_verification=True)
    beside = ScriptedSite(124.0, 10.0, roughness=0.5)
    m = make_mission([(0, 0, 100), (150, 0, 100)], [false_positive, beside],
                     landing={"landing_retries": 1, "landing_try_battery": 6.0,
                              "battery_reserve": 20.0},
                     vehicle={"battery": 26.5}, footprint=2.0)

    def drain(_tick):
        m.vehicle.battery = 26.5 - 6.0 * m.read(keys.VERIFICATION_ATTEMPTS)

    flight = m.fly(on_tick=drain)

    assert flight.status == Status.SUCCESS
    assert m.lsm.best_verified() is not None
    assert m.read(keys.OUTCOME_HINT) == "no_site"
    assert m.read(keys.FAILSAFE) is None
    assert xy_distance(m.vehicle.position, (false_positive.x, false_positive.y)) <= 1.0
    guard = next(n for n in m.tree.root.iterate() if n.name == "Battery allows the flight?")
    assert "battery 20.5 % leaves no room" in guard.feedback_message


def test_with_the_tries_spent_and_no_verified_site_it_lands_in_place():
    # The same flight without the site beside: nothing verified, so it lands where it is.
    false_positive = ScriptedSite(120.0, 10.0, roughness=0.05, fails_verification=True)
    m = make_mission([(0, 0, 100), (150, 0, 100)], [false_positive],
                     landing={"landing_retries": 1}, footprint=2.0)

    flight = m.fly()

    assert flight.status == Status.SUCCESS
    assert m.read(keys.OUTCOME_HINT) == "no_site"
    assert m.vehicle.commands[-1][0] == "land"
    assert xy_distance(m.vehicle.position, (false_positive.x, false_positive.y)) <= 1.0


def test_denied_takeoff_fails_the_mission_with_the_autopilot_reason():
    reason = "PreArm: Battery below minimum arming voltage"
    m = make_mission([(0, 0, 100)], [ScriptedSite(10, 0)], vehicle={"deny": {"takeoff": reason}})

    flight = m.fly()

    assert flight.status == Status.FAILURE
    assert reason in m.read(keys.FAILURE_REASON)
    assert "Takeoff" in m.read(keys.FAILURE_REASON)
    assert m.read(keys.PHASE) == "takeoff"
    assert flight.time < m.plan.landing.command_timeout
    assert m.vehicle.position[2] == 0.0


def test_denied_goto_fails_the_mission_instead_of_hanging():
    m = make_mission([(0, 0, 50), (80, 0, 50)], vehicle={"deny": {"goto": "Mode change denied"}})

    flight = m.fly()

    assert flight.status == Status.FAILURE
    assert "Mode change denied" in m.read(keys.FAILURE_REASON)


def test_unanswered_command_fails_after_the_command_timeout():
    m = make_mission([(0, 0, 50)], vehicle={"silent": {"takeoff"}}, landing={"command_timeout": 3})

    flight = m.fly()

    assert flight.status == Status.FAILURE
    assert "no answer within 3 s" in m.read(keys.FAILURE_REASON)
    assert flight.time >= 3.0


def test_preflight_waits_for_prearm_then_times_out_in_clock_time():
    m = make_mission([(0, 0, 50)], vehicle={"prearm_ok": False}, landing={"preflight_timeout": 20})

    flight = m.fly()

    assert flight.status == Status.FAILURE
    assert flight.time >= 20.0
    assert "timed out after 20 s" in m.read(keys.FAILURE_REASON)
    assert "prearm" in m.read(keys.FAILURE_REASON)
    assert m.vehicle.commands == []


def test_preflight_waits_for_the_autopilots_position_estimate():
    # ArduPilot's prearm bit is judged for STABILIZE; GUIDED still needs a position estimate.
    site = ScriptedSite(20.0, 0.0)
    m = make_mission([(20, 0, 20)], [site])
    m.vehicle.position_estimate = False
    commands_before = []

    def estimate_after_30_s(_tick):
        if m.clock.now() >= 30.0 and not m.vehicle.position_estimate:
            commands_before.extend(m.vehicle.commands)
            m.vehicle.position_estimate = True

    flight = m.fly(on_tick=estimate_after_30_s)

    assert commands_before == []
    assert_landed_at(m, flight, site)


def test_battery_reserve_skips_the_remaining_waypoints():
    site = ScriptedSite(60.0, 20.0)
    waypoints = [(0, 0, 100), (100, 0, 100), (200, 0, 100), (300, 0, 100)]
    m = make_mission(waypoints, [site])

    def drain(_tick):
        if m.vehicle.position[0] >= 50.0:
            m.vehicle.battery = 25.0

    flight = m.fly(on_tick=drain)

    assert_landed_at(m, flight, site)
    assert m.read(keys.OUTCOME_HINT) == "battery_reserve"
    targets = m.vehicle.gotos()
    assert (200.0, 0.0, 100.0) not in targets and (300.0, 0.0, 100.0) not in targets
    assert max(p[0] for p in flight.track) < 100.0


def test_critical_battery_lands_where_it_is():
    waypoints = [(0, 0, 100), (100, 0, 100), (200, 0, 100)]
    m = make_mission(waypoints, [ScriptedSite(150.0, 10.0)])
    trigger: list[tuple[float, float, float]] = []

    def drain(_tick):
        if not trigger and m.vehicle.position[0] >= 150.0:
            m.vehicle.battery = 10.0
            trigger.append(m.vehicle.position)

    flight = m.fly(on_tick=drain)

    assert flight.status == Status.SUCCESS
    assert m.read(keys.OUTCOME_HINT) == "battery_critical"
    assert m.read(keys.FAILSAFE) == "battery_critical"
    assert m.read(keys.PHASE) == "done"
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 0
    assert not m.vehicle.armed
    # One tick of travel at most between the battery reading and the land command.
    step = m.vehicle.speed * 0.1
    assert xy_distance(m.vehicle.position, trigger[0]) <= step + 1e-9
    assert max(p[0] for p in flight.track) <= trigger[0][0] + step + 1e-9


def test_critical_battery_during_verification_also_lands_in_place():
    site = ScriptedSite(120.0, 10.0, fails_verification=True)
    m = make_mission([(0, 0, 100), (150, 0, 100)], [site])

    def drain(_tick):
        if m.read(keys.PHASE) == "verification":
            m.vehicle.battery = 5.0

    flight = m.fly(on_tick=drain)

    assert flight.status == Status.SUCCESS
    assert m.read(keys.OUTCOME_HINT) == "battery_critical"
    assert m.read(keys.BANNED_SITES) == 0  # the verification was cut short, not failed
    assert xy_distance(m.vehicle.position, (site.x, site.y)) <= 1.0


def test_gps_dropout_is_ridden_out_but_a_lasting_loss_lands_in_place():
    site = ScriptedSite(150.0, 10.0)
    waypoints = [(0, 0, 100), (100, 0, 100), (200, 0, 100)]
    m = make_mission(waypoints, [site], landing={"gps_loss_timeout": 5.0})
    lost_at: list[tuple] = []

    def gps(_tick):
        x = m.vehicle.position[0]
        if 40.0 <= x < 60.0:
            m.vehicle.gps_fix = 1  # under 2 s at 12 m/s: a dropout
        elif x >= 120.0:
            if not lost_at:
                lost_at.append(m.vehicle.position)
            m.vehicle.gps_fix = 0
        else:
            m.vehicle.gps_fix = 3

    flight = m.fly(on_tick=gps)

    assert flight.status == Status.SUCCESS
    assert m.read(keys.FAILSAFE) == "gps_lost"
    assert m.read(keys.OUTCOME_HINT) == "gps_lost"
    assert m.read(keys.PHASE) == "done"
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 0
    # Landed where it was once the loss had lasted gps_loss_timeout of clock time.
    assert [name for name, _ in m.vehicle.commands].count("land") == 1
    assert m.vehicle.commands[-1][0] == "land"
    travelled = m.vehicle.position[0] - lost_at[0][0]
    assert travelled >= m.vehicle.speed * (5.0 - 0.2)
    assert travelled <= m.vehicle.speed * (5.0 + 0.2)


def test_at_the_battery_reserve_no_search_flies_and_it_lands_in_place():
    waypoints = [(0, 0, 100), (100, 0, 100), (200, 0, 100)]
    m = make_mission(waypoints, [], landing={"landing_retries": 3, "pattern_retries": 2})

    def drain(_tick):
        if m.vehicle.position[0] >= 50.0:
            m.vehicle.battery = 25.0

    flight = m.fly(on_tick=drain)

    assert flight.status == Status.SUCCESS
    assert m.read(keys.SEARCH_PATTERNS) == 0
    assert m.read(keys.OUTCOME_HINT) == "no_site"
    assert m.read(keys.PHASE) == "done"
    assert max(p[0] for p in flight.track) < 100.0
    assert [name for name, _ in m.vehicle.commands][-1] == "land"


def test_searching_stops_when_the_battery_reaches_the_reserve_mid_pattern():
    m = make_mission([(0, 0, 60), (50, 0, 60)], [], landing={"pattern_retries": 5})

    def drain(_tick):
        if m.read(keys.SEARCH_PATTERNS) >= 2:
            m.vehicle.battery = 29.0

    flight = m.fly(on_tick=drain)

    assert flight.status == Status.SUCCESS
    assert m.read(keys.SEARCH_PATTERNS) == 2
    assert m.read(keys.OUTCOME_HINT) == "no_site"


def test_a_mission_started_in_flight_climbs_without_a_takeoff_command():
    site = ScriptedSite(60.0, 10.0)
    m = make_mission([(0, 0, 80), (80, 0, 80)], [site], vehicle={"deny": {"takeoff": "flying"}})
    m.vehicle.armed, m.vehicle.position, m.vehicle.target = True, (0.0, 0.0, 30.0), (0, 0, 30)
    m.vehicle.prearm_ok = False  # autopilots report prearm checks only on the ground

    flight = m.fly()

    assert_landed_at(m, flight, site)
    assert m.vehicle.gotos()[0] == (0.0, 0.0, 80.0)
    assert "takeoff" not in [name for name, _ in m.vehicle.commands]


def fly_past_false_positives(battery: float, **landing):
    """Fly to (110, 0) past eight scripted sites around (115, 5) that all fail verification,
    from ``battery`` %, each landing try costing 6 %: the mission and its finished flight."""
    sites = [ScriptedSite(100.0 + 10.0 * (i % 4), 10.0 * (i // 4), fails_verification=True)
             for i in range(8)]
    m = make_mission([(0, 0, 100), (110, 0, 100)], sites, landing=landing,
                     vehicle={"battery": battery})

    def drain(_tick):
        m.vehicle.battery = battery - 6.0 * m.read(keys.VERIFICATION_ATTEMPTS)

    return m, m.fly(on_tick=drain)


def test_landing_tries_stop_while_the_battery_still_allows_a_landing_in_place():
    # Eight false positives near the last waypoint: every verification fails, and each try
    # costs 6 % of the battery. From 50 %: tries at 50, 44, 38, 32, 26; at 20 % another
    # 6 % try could end under the critical 15 %, so the phase stops and lands in place on
    # purpose, before the failsafe has anything to do.
    m, flight = fly_past_false_positives(50.0, landing_retries=12, landing_try_battery=5.0)

    assert flight.status == Status.SUCCESS
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 5
    assert m.read(keys.OUTCOME_HINT) == "no_site"
    assert m.read(keys.FAILSAFE) is None
    assert m.read(keys.PHASE) == "done"
    assert m.vehicle.battery == pytest.approx(20.0)
    assert not m.vehicle.armed and m.vehicle.commands[-1][0] == "land"
    phase = next(n for n in m.tree.root.iterate() if n.name == "Landing phase")
    assert "battery 20.0 % leaves no room for another try" in phase.feedback_message


def test_with_room_for_every_try_the_landing_phase_uses_them_all():
    # The same flight on a full battery: the try count ends the phase, not the battery.
    m, flight = fly_past_false_positives(100.0, landing_retries=4)

    assert flight.status == Status.SUCCESS
    assert m.read(keys.VERIFICATION_ATTEMPTS) == 4
    assert m.read(keys.OUTCOME_HINT) == "no_site"
    assert m.read(keys.FAILSAFE) is None
