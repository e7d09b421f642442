"""The landing tree as it was built in Python before it became data (behaviors/tree.py up to
the XML loader), kept verbatim as the reference the XML-built tree must fly like, tick for
tick."""

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
from behaviors.laser_guidance import BatteryAbove, FailsafeIs, LaserGuidance
from behaviors.ports import Clock, VehiclePort
from behaviors.search import GetNextPatternCenterWP, LandingSiteSearch
from behaviors.settings import MissionPlan
from behaviors.tree import MissionTree

if TYPE_CHECKING:
    from lsm import LandingSiteManager


def _within(child: py_trees.behaviour.Behaviour, clock: Clock, seconds: float) -> ClockTimeout:
    return ClockTimeout(f"{child.name} within {seconds:g} s", child, clock, seconds)


def _laser_guidance(s, vehicle, clock, rng) -> list:
    """After a GPS loss, follow a ground laser while the battery is above critical."""
    if not s.laser_guidance.enabled:
        return []
    return [
        Sequence(
            "Laser guidance",
            memory=False,
            children=[
                FailsafeIs("GPS lost failsafe?", "gps_lost"),
                BatteryAbove("Battery above critical?", vehicle, s.battery_critical),
                LaserGuidance("Follow the laser", vehicle, clock, s.laser_guidance,
                              rng=rng.spawn(1)[0], command_timeout=s.command_timeout),
                _within(
                    Land("Land over the laser", vehicle, clock, phase="failsafe",
                         outcome_hint="laser_guidance", command_timeout=s.command_timeout),
                    clock,
                    s.navigation_timeout,
                ),
            ],
        )
    ]


def legacy_mission_tree(
    plan: MissionPlan,
    vehicle: VehiclePort,
    lsm: LandingSiteManager,
    clock: Clock,
    rng: np.random.Generator,
) -> py_trees.trees.BehaviourTree:
    """The landing tree as the Python builder made it before the tree became data."""
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
            Selector(
                "Failsafe landing",
                memory=False,
                children=[
                    *_laser_guidance(s, vehicle, clock, rng),
                    _within(
                        Land("Land where it is", vehicle, clock, phase="failsafe",
                             command_timeout=cmd),
                        clock,
                        nav,
                    ),
                ],
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
