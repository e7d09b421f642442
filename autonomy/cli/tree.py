"""``lander tree MISSION.yaml``: print the mission's behaviour tree, optionally as dot or as
BehaviorTree.CPP v4 XML for Groot2."""

from __future__ import annotations

import argparse
import os

import numpy as np

from autonomy.clock import SimClock
from autonomy.errors import UserError
from behaviors.ports import VehicleState


class _OfflineVehicle:
    """A vehicle for building a tree that is never ticked: every command is refused."""

    state = VehicleState()

    def _refuse(self, *args, **kwargs):
        raise RuntimeError("lander tree: the tree is only displayed, not flown")

    arm = disarm = set_mode = takeoff = goto = set_velocity = hold = land = _refuse


def _same_file(a: str, b: str) -> bool:
    try:
        return os.path.samefile(a, b)
    except (OSError, ValueError):  # one of them does not exist (yet)
        return os.path.abspath(a) == os.path.abspath(b)


def _refuse_overwriting_inputs(args: argparse.Namespace, tree_file: str | None) -> None:
    """--dot and --xml write files: never over the mission file, its tree file or each
    other (the mission would be lost, or one output replaced by the other)."""
    inputs = [("the mission file", str(args.mission))]
    if tree_file:
        inputs.append(("the mission's tree file", str(tree_file)))
    for flag, target in (("--xml", args.xml), ("--dot", args.dot)):
        if not target:
            continue
        for what, path in inputs:
            if _same_file(target, path):
                raise UserError(f"{flag} {target}: is {what}; writing would replace it; "
                                "choose another file")
        inputs.append((f"the {flag} output", target))


def run(args: argparse.Namespace) -> int:
    from autonomy.cli.validate import load_or_explain
    from autonomy.runner.services import build_services, service_names
    from behaviors.display import render_ascii, write_dot
    from behaviors.tree import build_mission_tree, load_tree_file
    from behaviors.treexml import source_xml
    from lsm import LandingSiteManager

    mission = load_or_explain("tree", args.mission)
    if mission is None:
        return 2
    _refuse_overwriting_inputs(args, mission.tree)
    document = load_tree_file(mission.tree)
    tree = build_mission_tree(
        mission.plan(), _OfflineVehicle(), LandingSiteManager(mission.lsm, mission.weights),
        SimClock(), np.random.default_rng(mission.seed), document,
        # Displayed only, never ticked: no map to plan over, no camera to watch with.
        services={**dict.fromkeys(service_names(mission)), **build_services(mission, None)},
    )
    print(render_ascii(tree))
    if args.xml:
        try:
            with open(args.xml, "w", encoding="utf-8") as handle:
                handle.write(source_xml(document))
        except OSError as exc:
            raise UserError(f"--xml {args.xml}: {exc.strerror or exc}") from None
        print(f"xml: {args.xml}")
    if args.dot:
        try:
            write_dot(tree, args.dot)
        except OSError as exc:
            raise UserError(f"--dot {args.dot}: {exc.strerror or exc}") from None
        print(f"dot: {args.dot}")
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "tree", help="print the mission's behaviour tree",
        description="Print the behaviour tree a mission file builds (ASCII) and optionally "
        "write it as a Graphviz dot file, or as the BehaviorTree.CPP v4 XML tree file it is "
        "built from (the mission's tree: or the built-in landing tree) with a TreeNodesModel "
        "of every registered node, which Groot2 opens.",
    )
    parser.add_argument("mission", metavar="MISSION.yaml", help="mission file")
    parser.add_argument("--dot", metavar="FILE", help="write the tree as Graphviz dot source")
    parser.add_argument("--xml", metavar="FILE", help="write the tree file (BehaviorTree.CPP "
                        "v4 XML with the node models) for Groot2")
    parser.set_defaults(func=run)
