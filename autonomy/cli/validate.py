"""``lander validate MISSION.yaml``: check a mission file without flying it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from autonomy.config import Mission, MissionFileError, load_mission
from autonomy.errors import one_line


def load_or_explain(command: str, path: str | Path) -> Mission | None:
    """Load a mission; on problems print one ``lander COMMAND: error:`` line each to stderr
    and return None."""
    try:
        return load_mission(path)
    except MissionFileError as exc:
        for problem in exc.problems:
            print(f"lander {command}: error: {one_line(problem, 2000)}", file=sys.stderr)
        return None


def run(args: argparse.Namespace) -> int:
    mission = load_or_explain("validate", args.mission)
    if mission is None:
        return 2
    waypoints = len(mission.waypoints)
    print(
        f"ok: {args.mission}: {waypoints} waypoint{'s' * (waypoints != 1)}, "
        f"{mission.world.kind} world, {mission.perception.detector} detector, "
        f"{mission.vehicle.connection}" + (f", tree {mission.tree}" if mission.tree else "")
    )
    if mission.world.kind == "file":  # the model in metres: were its units taken right?
        from sitl.terrain.files import describe_elevation

        for line in describe_elevation(mission.world):  # the model, its window, notes
            print(line)
    if mission.geofence is not None:
        print(describe_geofence(mission))
    return 0


def describe_geofence(mission: Mission) -> str:
    """One line: the operating area, and whether the autopilot is to enforce it too."""
    fence = mission.geofence
    assert fence is not None
    ceiling = (f", ceiling {fence.max_altitude:g} m above home" if fence.max_altitude
               is not None else ", no ceiling")
    after = ("; the vehicle's own fence put back after landing" if fence.restore else
             "; left on the vehicle after landing (geofence.restore: false)")
    who = ("uploaded to the autopilot before takeoff, which enforces it too" + after
           if fence.upload else "kept by this software only (geofence.upload: false)")
    zones = len(fence.exclude)
    no_fly = f", {zones} no-fly zone{'' if zones == 1 else 's'}" if zones else ""
    return (f"geofence: {len(fence.polygon)} vertices{no_fly}, margin {fence.margin:g} m"
            f"{ceiling}; {who}")


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "validate", help="check a mission file (nothing is flown)",
        description="Check a mission file: prints 'ok' (exit 0) or one line per problem with "
        "file:line and field (exit 2). Nothing is flown.",
    )
    parser.add_argument("mission", metavar="MISSION.yaml", help="mission file")
    parser.set_defaults(func=run)
