"""The landing-mission behaviour tree (DESIGN.md section 5), built from a MissionPlan.

The tree is data: :data:`behaviors.loader.BUILTIN_TREE` (``landing_tree.xml``, BehaviorTree.CPP
v4 XML) holds the shape below, and :func:`build_mission_tree` builds it, or any tree file a
mission names, from the node registry (:mod:`behaviors.registry`).

::

    Landing mission (Selector, no memory: the failsafe is checked every tick)
     ├─ Failsafe (Sequence, memory)           [latched once it fires]
     │   ├─ Failsafe? = Selector[Battery critical?, GPS lost?]
     │   └─ Failsafe landing (Selector, no memory)
     │       ├─ Laser guidance (Sequence, no memory; landing.laser_guidance.enabled)
     │       │   [docs/gps-denied.md: the guards hold on every tick]
     │       │   ├─ GPS lost failsafe?     [FailsafeIs gps_lost]
     │       │   ├─ Battery above critical?
     │       │   ├─ Follow the laser       [LaserGuidance; latched once it gives up]
     │       │   └─ Land over the laser    [OUTCOME_HINT "laser_guidance"]
     │       └─ Land where it is            [OUTCOME_HINT: the failsafe's kind]
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

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import py_trees

from behaviors import ticking
from behaviors.loader import BUILTIN_TREE, TreeDocument, build_tree, read_tree
from behaviors.ports import Clock, VehiclePort
from behaviors.registry import BuildContext, mission_settings
from behaviors.settings import MissionPlan

if TYPE_CHECKING:
    from lsm import LandingSiteManager

_builtin: TreeDocument | None = None


def load_tree_file(path: str | Path | None = None) -> TreeDocument:
    """The parsed tree file ``path`` (None: the built-in landing tree, read once).

    Raises:
        behaviors.loader.TreeFileError: unreadable or malformed, one line per problem.
    """
    global _builtin
    if path is not None:
        return read_tree(path)
    if _builtin is None:
        _builtin = read_tree(BUILTIN_TREE)
    return _builtin


class MissionTree(py_trees.trees.BehaviourTree):
    """py_trees' tree whose tick walks only the behaviours it ticks.

    ``BehaviourTree.tick`` also walks every node after each tick for "full" visitors, which
    this project never adds; with a thousand waypoints that walk cost more than the tick.
    Here it runs only when a full visitor is there, so a tick costs what the ticked branch
    costs, however many waypoints the mission has. The tick is
    :func:`behaviors.ticking.run` (no generators), or :func:`behaviors.ticking.run_observed`
    showing the visitors each node where py_trees' tick would yield it.
    """

    def tick(self, pre_tick_handler=None, post_tick_handler=None) -> None:
        if self.visitors and any(visitor.full for visitor in self.visitors):
            super().tick(pre_tick_handler, post_tick_handler)
            return
        if pre_tick_handler is not None:
            pre_tick_handler(self)
        for handler in self.pre_tick_handlers:
            handler(self)
        visitors = self.visitors
        if visitors:
            for visitor in visitors:
                visitor.initialise()
            # Each node shown to the visitors where its tick would yield it (no generators);
            # py_trees' Behaviour.visit(visitor) is visitor.run(node).
            if len(visitors) == 1:
                ticking.run_observed(self.root, visitors[0].run)
            else:
                ticking.run_observed(
                    self.root, lambda node: [node.visit(visitor) for visitor in visitors]
                )
            for visitor in visitors:
                visitor.finalise()
        else:  # nobody looks at the nodes a tick passes
            ticking.run(self.root)
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
    tree_file: str | Path | TreeDocument | None = None,
    services: dict[str, Any] | None = None,
) -> MissionTree:
    """Build the landing-mission tree for ``plan`` from a tree file (see the module
    docstring for the built-in one's shape).

    Every blackboard key of :mod:`behaviors.blackboard` is reset to its start value, so build
    (and run) one mission at a time per process.

    Args:
        plan: waypoints, altitudes and landing settings.
        vehicle: the vehicle port (non-blocking commands, state snapshots).
        lsm: the Landing Site Manager the detector feeds; its ``settings.match_radius``
            decides which retained site is the chosen one during verification.
        clock: the injected clock every timeout and hover reads.
        rng: seeded generator for the random search-pattern centres.
        tree_file: a BehaviorTree.CPP v4 XML tree file (or one already read); None flies
            the built-in landing tree.
        services: what nodes need beyond the above, by the names of
            :data:`behaviors.registry.SERVICES` (an approach planner, an obstacle watch);
            a tree with a node whose service is missing is refused.

    Returns:
        the tree, not yet set up; tick it once per runner step. Its ``blackboard_keys``
        are the blackboard entries of the tree's own (beyond the mission keys).

    Raises:
        behaviors.loader.TreeFileError: the tree file's problems, one line each.
    """
    document = tree_file if isinstance(tree_file, TreeDocument) else load_tree_file(tree_file)
    settings = mission_settings(plan, lsm.settings.match_radius)
    context = BuildContext(vehicle, lsm, clock, rng, plan, dict(services or {}))
    root, extra = build_tree(document, settings, context)
    tree = MissionTree(root)
    tree.blackboard_keys = tuple(extra)
    return tree
