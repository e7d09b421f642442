"""The node registry: every node a tree file may use, with its typed ports.

Modelled on BehaviorTree.CPP v4 (``TreeNodeManifest``: a registration ID, a node type, and
``providedPorts()``): each :class:`NodeModel` has an ID (the XML tag), a kind (Action,
Condition, Control, Decorator), the number of children it takes, and :class:`Port` s with
a direction, a type, a unit and a default. :func:`models_element` writes them as the
``<TreeNodesModel>`` that Groot2 reads to offer the nodes in its palette.

A port's value in a tree file is one of

* a literal, converted by the port's type (``double`` as a number, ``bool`` as
  true/false, ``Point3D`` as ``x;y;z`` and ``Point2D`` as ``x;y``, BehaviorTree.CPP's
  separator);
* ``{name}`` of a **mission setting** (:func:`mission_settings`): its value is taken when
  the tree is built, e.g. ``seconds="{navigation_timeout}"``;
* ``{name}`` of a **blackboard entry**, for ports that are read or written while flying
  (``runtime`` ports, e.g. the chosen landing site): the mission's own entries have fixed
  names (:data:`BLACKBOARD_NAMES`), any other name is a new entry ``/tree/<name>``.

Mission settings are the mission's landing settings by field name (``acceptance_radius``,
``verify``, ``navigation_timeout``, ...; a sub-section's as ``section_field``, e.g.
``descent_watch_enabled``), plus ``cruise_altitude``, ``takeoff_altitude``
(the effective one), ``match_radius`` (the LSM's), ``last_waypoint`` (x;y of the last
mission waypoint), ``waypoint_count``, ``waypoint_1`` .. ``waypoint_N`` and
``laser_guidance`` (landing.laser_guidance.enabled); inside
``MissionWaypoints`` also ``waypoint`` and ``waypoint_number``.

The module is one table of every node, so it runs past 500 lines: splitting it would
scatter the registry a reader wants to see whole.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import py_trees
from py_trees.composites import Parallel
from pydantic import BaseModel

from behaviors import blackboard as keys
from behaviors.approach import FlyApproachTrajectory
from behaviors.decorators import ClockTimeout, RetryWhileBattery
from behaviors.descent_watch import WatchAborts, WatchedDescent, WatchedLand
from behaviors.failsafe import BatteryAllows, BatteryCritical, BatteryReserve, GpsLost, NoFailsafe
from behaviors.flight import (
    ChangeAltitudeLS,
    Land,
    NavigateToSite,
    NavigateToWaypoint,
    Preflight,
    Takeoff,
)
from behaviors.landing import (
    CheckLandingSite,
    GetClearAltitude,
    GetLandingSite,
    LandingSiteVerification,
)
from behaviors.laser_guidance import BatteryAbove, FailsafeIs, LaserGuidance
from behaviors.ports import Clock, VehiclePort
from behaviors.search import GetNextPatternCenterWP, LandingSiteSearch
from behaviors.settings import MissionPlan
from behaviors.ticking import Inverter, QuietDecorator, Retry, Selector, Sequence

if TYPE_CHECKING:
    from lsm import LandingSiteManager

Kind = Literal["Action", "Condition", "Control", "Decorator"]
Direction = Literal["input", "output", "inout"]

BLACKBOARD_NAMES: dict[str, str] = {
    "landing_site": keys.LANDING_SITE,
    "clear_altitude": keys.CLEAR_ALTITUDE,
    "pattern_center": keys.PATTERN_CENTER,
    "landing_try_cost": keys.LANDING_TRY_COST,
}
"""Blackboard entries a tree file names in ``{...}`` -> the mission's absolute keys."""


def blackboard_key(name: str) -> str:
    """The absolute py_trees key of a blackboard entry named in a tree file."""
    return BLACKBOARD_NAMES.get(name, f"/tree/{name}")


# --- port types -----------------------------------------------------------------------


class PortValueError(ValueError):
    """A port value that its type does not accept."""


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise PortValueError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise PortValueError(f"{text!r} is not a finite number")
    return value


def _integer(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise PortValueError(f"{text!r} is not an integer") from None


def _boolean(text: str) -> bool:
    if text.lower() in ("true", "1"):
        return True
    if text.lower() in ("false", "0"):
        return False
    raise PortValueError(f"{text!r} is not true or false")


def _point(size: int) -> Callable[[str], tuple[float, ...]]:
    def parse(text: str) -> tuple[float, ...]:
        parts = text.split(";")
        if len(parts) != size:
            raise PortValueError(f"{text!r} is not {size} numbers separated by ';'")
        return tuple(_number(p.strip()) for p in parts)

    return parse


def _no_literal(text: str) -> Any:
    raise PortValueError("takes a blackboard entry {name}, not a literal")


PARSERS: dict[str, Callable[[str], Any]] = {
    "double": _number,
    "int": _integer,
    "bool": _boolean,
    "std::string": str,
    "Point2D": _point(2),
    "Point3D": _point(3),
    "LandingSite": _no_literal,
}
"""Port type -> the function turning a literal into a value."""


def format_value(value: Any) -> str:
    """A value as a port's literal text (the inverse of :data:`PARSERS`)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (tuple, list)):
        return ";".join(format_value(float(v)) for v in value)
    return str(value)


def type_of(value: Any) -> str:
    """The port type a mission setting's value has."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, int):
        return "int"
    if isinstance(value, float):
        return "double"
    if isinstance(value, (tuple, list)):
        return f"Point{len(value)}D"
    return "std::string"


def accepts(port_type: str, value_type: str) -> bool:
    """True when a port of ``port_type`` takes a value of ``value_type`` (ints are
    doubles too)."""
    return port_type == value_type or (port_type == "double" and value_type == "int")


# --- models ---------------------------------------------------------------------------


@dataclass(frozen=True)
class Port:
    """A node's port (BehaviorTree.CPP ``PortInfo``).

    Attributes:
        name: the XML attribute.
        type: a key of :data:`PARSERS`.
        unit: "m", "s", "%" or "" (none).
        description: what it is.
        default: the XML text used when the attribute is absent; None: required.
        direction: input, output or inout (outputs and inouts are blackboard entries).
        runtime: the value is a blackboard entry read (or written) while flying; else it
            is fixed when the tree is built (a literal or a mission setting).
        optional: may be left out without a default (the node then does without).
    """

    name: str
    type: str
    unit: str = ""
    description: str = ""
    default: str | None = None
    direction: Direction = "input"
    runtime: bool = False
    optional: bool = False


SERVICES: dict[str, str] = {
    "approach_planner": "an approach planner (behaviors.ports.ApproachPlanner)",
    "obstacle_watch": "a descent camera's obstacle watch (behaviors.ports.ObstacleWatch)",
}
"""What some nodes need beyond the vehicle, LSM and clock, by name -> in words. The runner
passes those the mission provides (``build_mission_tree(..., services=...)``)."""


@dataclass
class BuildContext:
    """What nodes are built with: the vehicle port, the LSM, the clock, the seeded
    generator, the mission plan and the services of :data:`SERVICES` the mission has."""

    vehicle: VehiclePort
    lsm: LandingSiteManager
    clock: Clock
    rng: np.random.Generator
    plan: MissionPlan
    services: dict[str, Any] = field(default_factory=dict)


Builder = Callable[[BuildContext, str, dict[str, Any], list[py_trees.behaviour.Behaviour]],
                   py_trees.behaviour.Behaviour]


@dataclass(frozen=True)
class NodeModel:
    """A registered node: ID, kind, ports and how to build it.

    ``build(context, name, values, children)`` gets the port values by port name (build-
    time ports converted, runtime ports as absolute blackboard keys; ports left out
    without a default are absent) and the built children.
    """

    id: str
    kind: Kind
    description: str
    build: Builder
    ports: tuple[Port, ...] = ()
    children: tuple[int, int | None] = (0, 0)  # at least, at most (None: any number)
    default_name: Callable[[dict[str, str], list[str]], str] | None = None
    requires: tuple[str, ...] = ()  # keys of SERVICES the node needs

    def port(self, name: str) -> Port | None:
        return next((p for p in self.ports if p.name == name), None)


REGISTRY: dict[str, NodeModel] = {}
"""Every node a tree file may use, by ID."""


def register(model: NodeModel) -> NodeModel:
    """Add ``model`` to :data:`REGISTRY` (its ID must be new)."""
    if model.id in REGISTRY:
        raise ValueError(f"node {model.id} is registered already")
    REGISTRY[model.id] = model
    return model


# Ports many nodes share.
_RADIUS = Port("acceptance_radius", "double", "m", "a target counts as reached within this "
               "distance, horizontally and vertically", "{acceptance_radius}")
_COMMAND = Port("command_timeout", "double", "s", "a vehicle command not answered within "
                "this time fails the node", "{command_timeout}")
_SITE_IN = Port("site", "LandingSite", "", "the chosen landing site", "{landing_site}",
                runtime=True)
_RESERVE = Port("battery_reserve", "double", "%", "no flight starts or goes on at or below "
                "this battery level", "{battery_reserve}")
_PHASE = "the mission phase reported while it runs: " + ", ".join(keys.PHASES)


def _control(id: str, description: str, make, ports=()) -> None:
    register(NodeModel(id, "Control", description, make, tuple(ports), children=(1, None)))


_control("Sequence", "ticks its children in order until one fails; a running child is "
         "resumed on the next tick (py_trees Sequence with memory)",
         lambda c, n, v, ch: Sequence(n, memory=True, children=ch))
_control("ReactiveSequence", "ticks its children in order from the first on every tick "
         "(py_trees Sequence without memory)",
         lambda c, n, v, ch: Sequence(n, memory=False, children=ch))
_control("Fallback", "ticks its children in order until one succeeds; a running child is "
         "resumed on the next tick (py_trees Selector with memory)",
         lambda c, n, v, ch: Selector(n, memory=True, children=ch))
_control("ReactiveFallback", "ticks its children in order from the first on every tick, "
         "stopping a running one when an earlier child succeeds or runs (py_trees Selector "
         "without memory)", lambda c, n, v, ch: Selector(n, memory=False, children=ch))


def _parallel(c: BuildContext, name: str, v: dict[str, Any], children: list) -> Parallel:
    need = v["success_count"]
    if need not in (-1, 1, len(children)):
        raise ValueError(f"success_count must be 1, -1 or the number of children "
                         f"({len(children)}), got {need}")
    policy = (py_trees.common.ParallelPolicy.SuccessOnOne() if need == 1 and len(children) > 1
              else py_trees.common.ParallelPolicy.SuccessOnAll(synchronise=False))
    return Parallel(name, policy=policy, children=children)


_control("Parallel", "ticks every child on every tick; fails as soon as one fails, succeeds "
         "when success_count children succeeded (-1: all)", _parallel,
         [Port("success_count", "int", "", "children that must succeed: 1, or -1 for all",
               "-1")])


def _decorator(id: str, description: str, make, ports=(), default_name=None) -> None:
    register(NodeModel(id, "Decorator", description, make, tuple(ports), children=(1, 1),
                       default_name=default_name))


_decorator("Inverter", "SUCCESS of its child is FAILURE and FAILURE is SUCCESS",
           lambda c, n, v, ch: Inverter(n, ch[0]))
_decorator("RetryUntilSuccessful", "runs its child again after a failure, at most "
           "num_attempts times (py_trees Retry)",
           lambda c, n, v, ch: Retry(n, ch[0], v["num_attempts"]),
           [Port("num_attempts", "int", "", "tries, >= 1")])
_decorator(
    "ClockTimeout", "fails its child once it has run for `seconds` of the mission clock "
    "(simulated time in lockstep; BehaviorTree.CPP's Timeout reads the wall clock); unnamed, "
    "it is called '<child> within <seconds> s'",
    lambda c, n, v, ch: ClockTimeout(n, ch[0], c.clock, v["seconds"]),
    [Port("seconds", "double", "s", "time allowed, > 0")],
    default_name=lambda text, children: f"{children[0]} within {float(text['seconds']):g} s",
)
_decorator(
    "RetryWhileBattery", "runs its child again after a failure, at most num_attempts times "
    "and only while the battery, less what a try is expected to cost, stays at or above the "
    "critical level; writes that expected cost",
    lambda c, n, v, ch: RetryWhileBattery(
        n, ch[0], c.vehicle, v["num_attempts"], critical=v["critical"],
        attempt_cost=v["attempt_cost"], expected_cost_key=v.get("expected_cost")),
    [Port("num_attempts", "int", "", "tries, >= 1", "{landing_retries}"),
     Port("critical", "double", "%", "battery level no new try may be expected to cross",
          "{battery_critical}"),
     Port("attempt_cost", "double", "%", "battery a try is assumed to cost at least",
          "{landing_try_battery}"),
     Port("expected_cost", "double", "%", "the larger of attempt_cost and the largest drop "
          "of a try so far", "{landing_try_cost}", direction="output", runtime=True)],
)
_decorator(
    "MissionWaypoints", "expands, when the tree is built, into a Sequence (with memory) "
    "holding one copy of its child per mission waypoint; in each copy the mission settings "
    "`waypoint` (x;y;z) and `waypoint_number` (1..N) are set, and {waypoint_number} in a "
    "name is replaced by the number",
    lambda c, n, v, ch: Sequence(n, memory=True, children=ch),
)
register(NodeModel(
    "SubTree", "Decorator", "the tree with this ID, defined in the same file (it shares the "
    "mission's blackboard)", lambda c, n, v, ch: _SubTree(n, ch[0]), children=(0, 0)))


class _SubTree(QuietDecorator):
    """A subtree reference: mirrors its subtree's root."""

    def update(self) -> py_trees.common.Status:
        return self.decorated.status


def _leaf(id: str, kind: Kind, description: str, make, ports=(), requires=()) -> None:
    register(NodeModel(id, kind, description, make, tuple(ports), requires=tuple(requires)))


_leaf("NoFailsafe", "Condition", "SUCCESS while no failsafe has taken over the mission",
      lambda c, n, v, ch: NoFailsafe(n))
_leaf("BatteryCritical", "Condition", "latched: SUCCESS once the armed vehicle's battery is "
      "at or below `level` (the failsafe)",
      lambda c, n, v, ch: BatteryCritical(n, c.vehicle, v["level"]),
      [Port("level", "double", "%", "critical battery level", "{battery_critical}")])
_leaf("GpsLost", "Condition", "latched: SUCCESS once the armed vehicle has had no 3D GPS "
      "fix for `timeout`", lambda c, n, v, ch: GpsLost(n, c.vehicle, c.clock, v["timeout"]),
      [Port("timeout", "double", "s", "time without a 3D fix", "{gps_loss_timeout}")])
_leaf("BatteryReserve", "Condition", "SUCCESS when the battery is at or below `level`",
      lambda c, n, v, ch: BatteryReserve(n, c.vehicle, v["level"]),
      [Port("level", "double", "%", "reserve battery level", "{battery_reserve}")])
_leaf("BatteryAllows", "Condition", "SUCCESS when the battery less `cost` stays at or above "
      "`critical` (or the level is unknown)",
      lambda c, n, v, ch: BatteryAllows(n, c.vehicle, v["critical"], _cost(v["cost"])),
      [Port("critical", "double", "%", "battery level the flight must not cross",
            "{battery_critical}"),
       Port("cost", "double", "%", "battery the flight is expected to cost: a number, or a "
            "blackboard entry such as RetryWhileBattery's expected_cost",
            "{landing_try_cost}", runtime=True)])


def _cost(value: Any) -> Callable[[], float] | str:
    """A literal cost as a function, a blackboard key as is."""
    if isinstance(value, str):
        return value
    return lambda: value


_leaf("Preflight", "Action", "waits for link, position, 3D GPS fix, the autopilot's position "
      "estimate and prearm checks, then has the autopilot enforce the geofence when the mission "
      "uploads it (geofence.upload); fails at or below the battery reserve or when the "
      "autopilot refuses the fence",
      lambda c, n, v, ch: Preflight(
          n, c.vehicle, battery_reserve=v["battery_reserve"],
          fence=c.plan.geofence if c.plan.geofence_upload else None),
      [_RESERVE])
_leaf("Takeoff", "Action", "takes off to `altitude` above home (climbs with a goto when "
      "already flying)",
      lambda c, n, v, ch: Takeoff(n, c.vehicle, c.clock, v["altitude"],
                                  acceptance_radius=v["acceptance_radius"],
                                  command_timeout=v["command_timeout"]),
      [Port("altitude", "double", "m", "above home", "{takeoff_altitude}"), _RADIUS, _COMMAND])
_leaf("NavigateToWaypoint", "Action", "flies to an ENU waypoint; with a clear altitude it "
      "climbs to it first, traverses, then descends",
      lambda c, n, v, ch: NavigateToWaypoint(
          n, c.vehicle, c.clock, v["waypoint"], clear_altitude=v.get("clear_altitude"),
          acceptance_radius=v["acceptance_radius"], command_timeout=v["command_timeout"],
          phase=v["phase"]),
      [Port("waypoint", "Point3D", "m", "ENU x;y;z (z above home)"),
       Port("clear_altitude", "double", "m", "altitude to climb to before the traverse",
            optional=True),
       _RADIUS, _COMMAND, Port("phase", "std::string", "", _PHASE, "mission")])
_leaf("NavigateToSite", "Action", "climbs to the clear altitude, flies over the chosen site",
      lambda c, n, v, ch: NavigateToSite(
          n, c.vehicle, c.clock, acceptance_radius=v["acceptance_radius"],
          command_timeout=v["command_timeout"], site_key=v["site"],
          clear_altitude_key=v["clear_altitude"]),
      [_SITE_IN, Port("clear_altitude", "double", "m", "altitude of the traverse",
                      "{clear_altitude}", runtime=True), _RADIUS, _COMMAND])
_leaf("ChangeAltitudeLS", "Action", "descends (or climbs) to `height` above the chosen site",
      lambda c, n, v, ch: ChangeAltitudeLS(
          n, c.vehicle, c.clock, v["height"], acceptance_radius=v["acceptance_radius"],
          command_timeout=v["command_timeout"], phase=v["phase"], site_key=v["site"]),
      [Port("height", "double", "m", "above the site", "{verification_altitude}"), _SITE_IN,
       _RADIUS, _COMMAND, Port("phase", "std::string", "", _PHASE, "descend")])
_leaf("Land", "Action", "lands where the vehicle is; SUCCESS once landed and disarmed",
      lambda c, n, v, ch: Land(n, c.vehicle, c.clock, phase=v["phase"],
                               outcome_hint=v.get("outcome_hint"),
                               command_timeout=v["command_timeout"]),
      [Port("phase", "std::string", "", _PHASE, "land"),
       Port("outcome_hint", "std::string", "", "why the mission lands here, for the report: "
            "no_site, verified_site, battery_critical, gps_lost", optional=True), _COMMAND])
_leaf("CheckLandingSite", "Condition", "SUCCESS when the LSM holds a landing site",
      lambda c, n, v, ch: CheckLandingSite(n, c.lsm))
_GET_PORTS = [
    Port("buffer", "double", "m", "z_buffer of the clear altitude (thesis eq. 3.4)",
         "{clear_altitude_buffer}"),
    Port("failsafe_altitude", "double", "m", "cap of the clear altitude (eq. 3.5)",
         "{failsafe_altitude}"),
]
_leaf("GetLandingSite", "Action", "chooses the best (or best verified) site of the LSM and "
      "its clear altitude",
      lambda c, n, v, ch: GetLandingSite(
          n, c.vehicle, c.lsm, buffer=v["buffer"], failsafe_altitude=v["failsafe_altitude"],
          verified_only=v["verified_only"], site_key=v["site"],
          clear_altitude_key=v["clear_altitude"], area=c.plan.geofence),
      [*_GET_PORTS, Port("verified_only", "bool", "", "only verified sites", "false"),
       Port("site", "LandingSite", "", "the chosen site", "{landing_site}", "output", True),
       Port("clear_altitude", "double", "m", "its clear altitude", "{clear_altitude}",
            "output", True)])
_leaf("GetClearAltitude", "Action", "computes the clear altitude of the chosen site",
      lambda c, n, v, ch: GetClearAltitude(
          n, c.vehicle, buffer=v["buffer"], failsafe_altitude=v["failsafe_altitude"],
          site_key=v["site"], clear_altitude_key=v["clear_altitude"]),
      [*_GET_PORTS, _SITE_IN,
       Port("clear_altitude", "double", "m", "the clear altitude", "{clear_altitude}",
            "output", True)])
_leaf("LandingSiteVerification", "Action", "hovers over the chosen site waiting for its "
      "re-detection from low altitude; bans it on failure",
      lambda c, n, v, ch: LandingSiteVerification(
          n, c.vehicle, c.lsm, c.clock, duration=v["duration"],
          match_radius=v["match_radius"], height=v["height"],
          recentre_distance=v["recentre_distance"], command_timeout=v["command_timeout"],
          site_key=v["site"], fresh=v["fresh"]),
      [Port("duration", "double", "s", "hover time", "{verification_duration}"),
       Port("fresh", "bool", "", "only a re-detection during this hover verifies",
            "{verify_fresh}"),
       Port("match_radius", "double", "m", "a retained site this close is the same",
            "{match_radius}"),
       Port("height", "double", "m", "hover height above the site", "{verification_altitude}"),
       Port("recentre_distance", "double", "m", "follow the site when its record moves "
            "farther", "{centring_radius}"),
       _COMMAND,
       Port("site", "LandingSite", "", "the chosen site (replaced by the verified record)",
            "{landing_site}", "inout", True)])
_leaf("LandingSiteSearch", "Action", "flies a rectangle until the LSM holds a site",
      lambda c, n, v, ch: LandingSiteSearch(
          n, c.vehicle, c.clock, c.lsm, size=v["size"], altitude=v["altitude"],
          use_pattern_center=v["use_pattern_center"], battery_reserve=v["battery_reserve"],
          acceptance_radius=v["acceptance_radius"], command_timeout=v["command_timeout"],
          pattern_center_key=v["pattern_center"], area=c.plan.geofence),
      [Port("size", "Point2D", "m", "width (east);height (north)", "{search_rectangle}"),
       Port("altitude", "double", "m", "flown at", "{cruise_altitude}"),
       Port("use_pattern_center", "bool", "", "centre on pattern_center, else where the "
            "vehicle is", "false"),
       Port("pattern_center", "Point2D", "m", "the centre GetNextPatternCenterWP drew",
            "{pattern_center}", runtime=True),
       _RESERVE, _RADIUS, _COMMAND])
_leaf("GetNextPatternCenterWP", "Action", "draws a new pattern centre (seeded) within "
      "`radius` of `anchor` and flies there",
      lambda c, n, v, ch: GetNextPatternCenterWP(
          n, c.vehicle, c.clock, c.rng, anchor=v["anchor"], radius=v["radius"],
          altitude=v["altitude"], battery_reserve=v["battery_reserve"],
          acceptance_radius=v["acceptance_radius"], command_timeout=v["command_timeout"],
          pattern_center_key=v["pattern_center"], area=c.plan.geofence),
      [Port("anchor", "Point2D", "m", "ENU x;y the centres are drawn around",
            "{last_waypoint}"),
       Port("radius", "double", "m", "of the disc drawn from", "{pattern_center_radius}"),
       Port("altitude", "double", "m", "flown at", "{cruise_altitude}"),
       Port("pattern_center", "Point2D", "m", "the centre drawn", "{pattern_center}",
            "output", True),
       _RESERVE, _RADIUS, _COMMAND])

_leaf("LaserGuidance", "Action", "after a GPS loss: waits for a ground laser, flies its "
      "bearing by velocity commands and descends over it; SUCCESS over the laser at "
      "land_height, FAILURE (latched) when there is no laser to follow (the mission's "
      "landing.laser_guidance settings; its estimator draws from a generator spawned from "
      "the mission's)",
      lambda c, n, v, ch: LaserGuidance(n, c.vehicle, c.clock, c.plan.landing.laser_guidance,
                                        rng=c.rng.spawn(1)[0],
                                        command_timeout=v["command_timeout"]),
      [_COMMAND])
_leaf("FailsafeIs", "Condition", "SUCCESS when the failsafe that took over is `kind`",
      lambda c, n, v, ch: FailsafeIs(n, v["kind"]),
      [Port("kind", "std::string", "", "battery_critical or gps_lost")])
_leaf("BatteryAbove", "Condition", "SUCCESS while the battery is above `level` (or unknown)",
      lambda c, n, v, ch: BatteryAbove(n, c.vehicle, v["level"]),
      [Port("level", "double", "%", "battery level", "{battery_critical}")])

_leaf("FlyApproachTrajectory", "Action", "flies to above the chosen site (landing_site) "
      "along a trajectory planned over the known terrain; FAILURE hands over to the next "
      "child of a Fallback, e.g. NavigateToSite",
      lambda c, n, v, ch: FlyApproachTrajectory(
          n, c.vehicle, c.clock, c.services["approach_planner"], min_height=v["min_height"],
          acceptance_radius=v["acceptance_radius"],
          max_tracking_error=v["max_tracking_error"], command_timeout=v["command_timeout"],
          area=c.plan.geofence),
      [Port("min_height", "double", "m", "the trajectory ends this high above the site",
            "{approach_min_height}"),
       Port("max_tracking_error", "double", "m", "farther from the trajectory fails",
            "{approach_max_tracking_error}"),
       _RADIUS, _COMMAND], requires=["approach_planner"])
_BAN_AFTER = Port("ban_after", "int", "", "retreats from one site before it is banned "
                  "(0: never)", "{descent_watch_ban_after}")

_COLUMN_MARGIN = Port("column_margin", "double", "m", "the rangefinder's ground rising this "
                      "much is something in the column", "{descent_watch_column_margin}")


def _watch_aborts(context: BuildContext) -> WatchAborts:
    """The tree's one count of the watch's retreats per site (shared by its watched nodes)."""
    return context.services.setdefault("watch_aborts", WatchAborts())


_leaf("WatchedDescent", "Action", "descends to `height` above the chosen site (landing_site) "
      "while the descent camera's optical flow watches for obstacles, stepping away from them",
      lambda c, n, v, ch: WatchedDescent(
          n, c.vehicle, c.clock, v["height"], c.services["obstacle_watch"], step=v["step"],
          max_offset=v["max_offset"], settle=v["settle"],
          acceptance_radius=v["acceptance_radius"], command_timeout=v["command_timeout"],
          phase=v["phase"], lsm=c.lsm, aborts=_watch_aborts(c), ban_after=v["ban_after"],
          column_margin=v["column_margin"]),
      [Port("height", "double", "m", "above the site", "{verification_altitude}"),
       _BAN_AFTER, _COLUMN_MARGIN,
       Port("step", "double", "m", "a step away from an obstacle", "{descent_watch_step}"),
       Port("max_offset", "double", "m", "farthest from the site's column",
            "{descent_watch_max_offset}"),
       Port("settle", "double", "s", "sightings ignored after a step",
            "{descent_watch_settle}"),
       _RADIUS, _COMMAND, Port("phase", "std::string", "", _PHASE, "descend")],
      requires=["obstacle_watch"])
_leaf("WatchedLand", "Action", "lands where the vehicle is while the descent camera's "
      "optical flow and the rangefinder watch the column; an obstacle aborts the landing "
      "with a climb to `height` above the site and FAILURE (the site banned after "
      "`ban_after` retreats); SUCCESS once landed and disarmed",
      lambda c, n, v, ch: WatchedLand(
          n, c.vehicle, c.clock, c.services["obstacle_watch"], height=v["height"], lsm=c.lsm,
          aborts=_watch_aborts(c), ban_after=v["ban_after"], settle=v["settle"],
          column_margin=v["column_margin"], acceptance_radius=v["acceptance_radius"],
          phase=v["phase"], outcome_hint=v.get("outcome_hint"),
          command_timeout=v["command_timeout"]),
      [Port("height", "double", "m", "climbed back to above the site when aborting",
            "{verification_altitude}"),
       _BAN_AFTER,
       Port("settle", "double", "s", "sightings ignored after the landing began",
            "{descent_watch_settle}"),
       _COLUMN_MARGIN,
       Port("phase", "std::string", "", _PHASE, "land"),
       Port("outcome_hint", "std::string", "", "why the mission lands here, for the report",
            optional=True), _RADIUS, _COMMAND],
      requires=["obstacle_watch"])


def mission_settings(plan: MissionPlan, match_radius: float) -> dict[str, Any]:
    """The mission settings a tree file may name in ``{...}`` (see the module docstring)."""
    settings: dict[str, Any] = {  # the landing section's numbers, flags and pairs
        name: value for name, value in plan.landing
        if isinstance(value, (bool, int, float)) or (
            isinstance(value, tuple) and len(value) in (2, 3))}
    for section, model in plan.landing:  # its sub-sections' too: descent_watch_enabled, ...
        if isinstance(model, BaseModel):
            settings.update({f"{section}_{name}": value for name, value in model
                             if isinstance(value, (bool, int, float))})
    # The approach's method is a word; the tree file asks whether it is the trajectory.
    settings["approach_trajectory"] = plan.landing.approach.method == "trajectory"
    watch = plan.landing.descent_watch
    settings["watch_landing"] = watch.enabled and watch.land
    last = plan.waypoints[-1]
    settings.update(
        cruise_altitude=plan.cruise_altitude,
        takeoff_altitude=plan.effective_takeoff_altitude,
        match_radius=float(match_radius),
        last_waypoint=(float(last[0]), float(last[1])),
        waypoint_count=len(plan.waypoints),
        laser_guidance=plan.landing.laser_guidance.enabled,
    )
    for i, waypoint in enumerate(plan.waypoints):
        settings[f"waypoint_{i + 1}"] = tuple(float(v) for v in waypoint)
    return settings


def models_element() -> ET.Element:
    """Every registered node as BehaviorTree.CPP's ``<TreeNodesModel>`` (sorted by ID, as
    BehaviorTree.CPP writes it), ports with type, default and "[unit] description"."""
    models = ET.Element("TreeNodesModel")
    for node_id in sorted(REGISTRY):
        model = REGISTRY[node_id]
        if node_id == "SubTree":
            continue
        element = ET.SubElement(models, model.kind, {"ID": node_id})
        for port in sorted(model.ports, key=lambda p: p.name):
            attributes = {"name": port.name, "type": port.type}
            if port.default is not None:
                attributes["default"] = port.default
            child = ET.SubElement(element, f"{port.direction}_port", attributes)
            unit = f"[{port.unit}] " if port.unit else ""
            child.text = unit + port.description
        metadata = ET.SubElement(element, "MetadataFields")
        ET.SubElement(metadata, "Metadata", {"description": model.description})
    return models

