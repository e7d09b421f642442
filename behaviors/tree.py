"""The landing-mission behaviour tree (DESIGN.md section 5), built from a MissionPlan.

::

    Landing mission (Selector, no memory: the failsafe is checked every tick)
     ├─ Failsafe (Sequence, memory)           [latched once it fires]
     │   ├─ Failsafe? = Selector[Battery critical?, GPS lost?]
     │   └─ Land where it is                [OUTCOME_HINT: the failsafe's kind]
     └─ Mission (Sequence, memory)
         ├─ No failsafe?                       [a mission ended by the failsafe never restarts]
         ├─ Preflight                          [link, position, GPS fix, prearm; clock timeout]
         ├─ Takeoff                            [to the first waypoint's altitude]
         ├─ Waypoints (Selector, no memory)
         │   ├─ Battery reserve?               [SUCCESS skips the remaining waypoints]
         │   └─ Mission waypoints (Sequence of NavigateToWaypoint)
         └─ Landing (Selector, memory)
             ├─ Landing phase = RetryWhileBattery(N) ─ Landing attempt (Sequence, memory)
             │   [a new try only if it is not expected to reach the critical battery level]
             │   ├─ Ensure sites = Selector[CheckLandingSite, LandingSiteSearch,
             │   │                          Retry(M) ─ Sequence[GetNextPatternCenterWP,
             │   │                                              LandingSiteSearch]]
             │   │                 [searching stops at the battery reserve]
             │   ├─ GetLandingSite
             │   ├─ NavigateToSite             [clear altitude, over the site]
             │   ├─ ChangeAltitudeLS           [verification altitude above the site]
             │   ├─ LandingSiteVerification    [bans the site on failure; landing.verify]
             │   ├─ Centre over verified site  [ChangeAltitudeLS to the verified record]
             │   └─ Land
             ├─ Last resort: a verified site (Sequence, memory)  [OUTCOME_HINT "verified_site"]
             │   [the tries are spent, but a site was verified meanwhile, e.g. beside
             │    the last one tried: land there without another hover]
             │   ├─ Battery allows the flight?  [what a try has cost, above the critical level]
             │   ├─ GetLandingSite (verified sites only)
             │   ├─ NavigateToSite
             │   ├─ Descend over the verified site [centring radius]
             │   └─ Land
             └─ Land in place                  [OUTCOME_HINT "no_site"]

The landing phase learns what a try costs (the largest battery drop of a finished try, at
least ``landing_try_battery``) and stops trying while there is still room to land in place
above the critical level. A flight that runs out of tries or of battery then lands on
purpose rather than being caught mid-try by the failsafe: on the best verified site the LSM
holds, if any and if the battery allows what a try has cost (outcome hint "verified_site";
no new hover, the site was already seen safe from the verification altitude, e.g. by the
last hover beside the site that failed), else in place (outcome hint "no_site"). The
failsafe's own landing, wherever the vehicle is, is reported as its own outcome
(OUTCOME_HINT "battery_critical" or "gps_lost"). The pattern retries keep py_trees' plain
``Retry``: every search behaviour already stops at the battery reserve, a stricter bound
than the critical level, and a search cut short only ends the search.

Every action that flies or waits runs under a :class:`~behaviors.decorators.ClockTimeout`
(``navigation_timeout``; ``preflight_timeout`` for Preflight); a denied or unanswered
command fails its action at once.

The root returns SUCCESS once the vehicle has landed and disarmed (at a site or in place),
FAILURE when the mission failed (FAILURE_REASON says why, e.g. a denied command with the
autopilot's reason), RUNNING otherwise. Stop ticking once it is no longer RUNNING.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import py_trees
from py_trees.composites import Selector, Sequence
from py_trees.decorators import Retry

from behaviors import blackboard
from behaviors.decorators import ClockTimeout, RetryWhileBattery
from behaviors.failsafe import (
    BatteryAllows,
    BatteryCritical,
    BatteryReserve,
    GpsLost,
    NoFailsafe,
)
from behaviors.flight import (
    ChangeAltitudeLS,
    Land,
    NavigateToSite,
    NavigateToWaypoint,
    Preflight,
    Takeoff,
)
from behaviors.landing import CheckLandingSite, GetLandingSite, LandingSiteVerification
from behaviors.ports import Clock, VehiclePort
from behaviors.search import GetNextPatternCenterWP, LandingSiteSearch
from behaviors.settings import MissionPlan

if TYPE_CHECKING:
    from lsm import LandingSiteManager


def _within(child: py_trees.behaviour.Behaviour, clock: Clock, seconds: float) -> ClockTimeout:
    return ClockTimeout(f"{child.name} within {seconds:g} s", child, clock, seconds)


class MissionTree(py_trees.trees.BehaviourTree):
    """py_trees' tree whose tick walks only the behaviours it ticks.

    ``BehaviourTree.tick`` also walks every node after each tick for "full" visitors, which
    this project never adds; with a thousand waypoints that walk cost more than the tick.
    Here it runs only when a full visitor is there, so a tick costs what the ticked branch
    costs, however many waypoints the mission has.
    """

    def tick(self, pre_tick_handler=None, post_tick_handler=None) -> None:
        if any(visitor.full for visitor in self.visitors):
            super().tick(pre_tick_handler, post_tick_handler)
            return
        if pre_tick_handler is not None:
            pre_tick_handler(self)
        for handler in self.pre_tick_handlers:
            handler(self)
        for visitor in self.visitors:
            visitor.initialise()
        for node in self.root.tick():
            for visitor in self.visitors:
                node.visit(visitor)
        for visitor in self.visitors:
            visitor.finalise()
        for handler in self.post_tick_handlers:
            handler(self)
        if post_tick_handler is not None:
            post_tick_handler(self)
        self.count += 1


def build_mission_tree(
    plan: MissionPlan,
    vehicle: VehiclePort,
    lsm: LandingSiteManager,
    clock: Clock,
    rng: np.random.Generator,
) -> py_trees.trees.BehaviourTree:
    """Build the landing-mission tree for ``plan`` (see the module docstring for its shape).

    Every blackboard key of :mod:`behaviors.blackboard` is reset to its start value, so build
    (and run) one mission at a time per process.

    Args:
        plan: waypoints, altitudes and landing settings.
        vehicle: the vehicle port (non-blocking commands, state snapshots).
        lsm: the Landing Site Manager the detector feeds; its ``settings.match_radius``
            decides which retained site is the chosen one during verification.
        clock: the injected clock every timeout and hover reads.
        rng: seeded generator for the random search-pattern centres.

    Returns:
        the tree, not yet set up; tick it once per runner step.
    """
    s = plan.landing
    radius = s.acceptance_radius
    cmd = s.command_timeout
    nav = s.navigation_timeout

    blackboard.reset()
    blackboard.initialise()

    failsafe = Sequence(
        "Failsafe",
        memory=True,
        children=[
            Selector(
                "Failsafe?",
                memory=False,
                children=[
                    BatteryCritical("Battery critical?", vehicle, s.battery_critical),
                    GpsLost("GPS lost?", vehicle, clock, s.gps_loss_timeout),
                ],
            ),
            _within(
                Land("Land where it is", vehicle, clock, phase="failsafe", command_timeout=cmd),
                clock,
                nav,
            ),
        ],
    )

    waypoints = Sequence(
        "Mission waypoints",
        memory=True,
        children=[
            _within(
                NavigateToWaypoint(
                    f"Waypoint {i + 1}",
                    vehicle,
                    clock,
                    wp,
                    acceptance_radius=radius,
                    command_timeout=cmd,
                ),
                clock,
                nav,
            )
            for i, wp in enumerate(plan.waypoints)
        ],
    )

    def search(name: str, use_pattern_center: bool) -> ClockTimeout:
        return _within(
            LandingSiteSearch(
                name,
                vehicle,
                clock,
                lsm,
                size=s.search_rectangle,
                altitude=plan.cruise_altitude,
                use_pattern_center=use_pattern_center,
                battery_reserve=s.battery_reserve,
                acceptance_radius=radius,
                command_timeout=cmd,
            ),
            clock,
            nav,
        )

    last_x, last_y, _ = plan.waypoints[-1]
    new_pattern = Retry(
        "Pattern retries",
        Sequence(
            "New pattern",
            memory=True,
            children=[
                _within(
                    GetNextPatternCenterWP(
                        "GetNextPatternCenterWP",
                        vehicle,
                        clock,
                        rng,
                        anchor=(last_x, last_y),
                        radius=s.pattern_center_radius,
                        altitude=plan.cruise_altitude,
                        battery_reserve=s.battery_reserve,
                        acceptance_radius=radius,
                        command_timeout=cmd,
                    ),
                    clock,
                    nav,
                ),
                search("Search at the new centre", use_pattern_center=True),
            ],
        ),
        s.pattern_retries,
    )
    ensure_sites = Selector(
        "Ensure sites",
        memory=True,
        children=[
            CheckLandingSite("CheckLandingSite", lsm),
            search("LandingSiteSearch", use_pattern_center=False),
            new_pattern,
        ],
    )
    # Re-detect from low altitude, then centre over the verified record (the low look may
    # move it up to the match radius); skipped when the mission turns verification off.
    verification = (
        [
            LandingSiteVerification(
                "LandingSiteVerification",
                vehicle,
                lsm,
                clock,
                duration=s.verification_duration,
                match_radius=lsm.settings.match_radius,
                height=s.verification_altitude,
                recentre_distance=s.centring_radius,
                command_timeout=cmd,
            ),
            _within(
                ChangeAltitudeLS(
                    "Centre over verified site",
                    vehicle,
                    clock,
                    s.verification_altitude,
                    acceptance_radius=s.centring_radius,
                    command_timeout=cmd,
                    phase="centre",
                ),
                clock,
                nav,
            ),
        ]
        if s.verify
        else []
    )
    attempt = Sequence(
        "Landing attempt",
        memory=True,
        children=[
            ensure_sites,
            GetLandingSite(
                "GetLandingSite",
                vehicle,
                lsm,
                buffer=s.clear_altitude_buffer,
                failsafe_altitude=s.failsafe_altitude,
            ),
            _within(
                NavigateToSite(
                    "NavigateToSite", vehicle, clock, acceptance_radius=radius, command_timeout=cmd
                ),
                clock,
                nav,
            ),
            _within(
                ChangeAltitudeLS(
                    "ChangeAltitudeLS",
                    vehicle,
                    clock,
                    s.verification_altitude,
                    acceptance_radius=radius,
                    command_timeout=cmd,
                ),
                clock,
                nav,
            ),
            *verification,
            _within(Land("Land", vehicle, clock, command_timeout=cmd), clock, nav),
        ],
    )
    landing_phase = RetryWhileBattery(
        "Landing phase",
        attempt,
        vehicle,
        s.landing_retries,
        critical=s.battery_critical,
        attempt_cost=s.landing_try_battery,
    )
    # After the last try: a site verified along the way (seen safe from the verification
    # altitude, not banned) beats landing blind over the site that just failed, if the
    # battery allows the flight (bounded by what a whole try has cost, hover included).
    last_resort = Sequence(
        "Last resort: a verified site",
        memory=True,
        children=[
            BatteryAllows(
                "Battery allows the flight?",
                vehicle,
                critical=s.battery_critical,
                cost=lambda: landing_phase.expected_cost,
            ),
            GetLandingSite(
                "Get a verified site",
                vehicle,
                lsm,
                buffer=s.clear_altitude_buffer,
                failsafe_altitude=s.failsafe_altitude,
                verified_only=True,
            ),
            _within(
                NavigateToSite(
                    "Fly to the verified site",
                    vehicle,
                    clock,
                    acceptance_radius=radius,
                    command_timeout=cmd,
                ),
                clock,
                nav,
            ),
            _within(
                ChangeAltitudeLS(
                    "Descend over the verified site",
                    vehicle,
                    clock,
                    s.verification_altitude,
                    acceptance_radius=s.centring_radius,
                    command_timeout=cmd,
                ),
                clock,
                nav,
            ),
            _within(
                Land(
                    "Land on the verified site",
                    vehicle,
                    clock,
                    outcome_hint="verified_site",
                    command_timeout=cmd,
                ),
                clock,
                nav,
            ),
        ],
    )
    landing = Selector(
        "Landing",
        memory=True,
        children=[
            landing_phase,
            last_resort,
            _within(
                Land(
                    "Land in place",
                    vehicle,
                    clock,
                    phase="land_in_place",
                    outcome_hint="no_site",
                    command_timeout=cmd,
                ),
                clock,
                nav,
            ),
        ],
    )

    mission = Sequence(
        "Mission",
        memory=True,
        children=[
            NoFailsafe("No failsafe?"),
            ClockTimeout(
                f"Preflight within {s.preflight_timeout:g} s",
                Preflight("Preflight", vehicle, battery_reserve=s.battery_reserve),
                clock,
                s.preflight_timeout,
            ),
            _within(
                Takeoff(
                    "Takeoff",
                    vehicle,
                    clock,
                    plan.effective_takeoff_altitude,
                    acceptance_radius=radius,
                    command_timeout=cmd,
                ),
                clock,
                nav,
            ),
            Selector(
                "Waypoints",
                memory=False,
                children=[
                    BatteryReserve("Battery reserve?", vehicle, s.battery_reserve),
                    waypoints,
                ],
            ),
            landing,
        ],
    )

    root = Selector("Landing mission", memory=False, children=[failsafe, mission])
    return MissionTree(root)
