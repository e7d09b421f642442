"""``lander fly MISSION.yaml``: fly a mission and write its flight report."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import yaml

from autonomy.cli import args as types
from autonomy.cli.outdir import check_flight_folder, writing_into
from autonomy.cli.validate import load_or_explain
from autonomy.config import apply_overrides, read_yaml_value
from autonomy.errors import UserError
from autonomy.report.summary import EXIT_MEANINGS


def parse_settings(items: list[str]) -> dict[str, Any]:
    """``KEY=VALUE`` strings to overrides; values are read as YAML, as in mission files
    (``5``, ``1e3``, ``[1, 2]``, ``false``, ``text``)."""
    overrides: dict[str, Any] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise UserError(f"--set {item}: expected KEY=VALUE, e.g. landing.verification_"
                            "altitude=5")
        try:
            overrides[key.strip()] = read_yaml_value(text) if text.strip() else ""
        except (yaml.YAMLError, RecursionError):
            raise UserError(f"--set {item}: the value is not valid YAML") from None
    return overrides


def run(args: argparse.Namespace) -> int:
    mission = load_or_explain("fly", args.mission)
    if mission is None:
        return 2
    overrides = parse_settings(args.set or [])
    if args.connect is not None:
        overrides["vehicle.connection"] = args.connect
    if args.home_from is not None:
        overrides["vehicle.home_from"] = args.home_from
    if overrides:
        mission = apply_overrides(mission, overrides)
    out = Path(args.out) if args.out else Path("out") / Path(args.mission).stem
    check_flight_folder(out)
    from autonomy.runner import fly

    with writing_into(out, "the flight's report"):
        result = fly(mission, seed=args.seed, out_dir=out, console=not args.quiet,
                     on_interrupt=args.on_interrupt)
    if args.quiet:
        print(f"{result.outcome} (exit {result.exit_code}): report {out / 'report.png'}")
    return result.exit_code


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "fly", help="fly a mission and write its flight report",
        description="Fly a mission: lockstep on the embedded SITL for sim://, live over "
        "MAVLink otherwise (on the vehicle's own time; lat/lon waypoints converted about the "
        "home the vehicle reports). Writes summary.json, events.jsonl, flight.tlog, "
        "report.png and report.html (lander replay DIR opens it) to --out whatever ends the "
        "flight.",
        epilog="exit codes: " + "; ".join(
            f"{code} = {meaning}" for code, meaning in sorted(EXIT_MEANINGS.items())
        ) + ".",
    )
    parser.add_argument("mission", metavar="MISSION.yaml", help="mission file")
    parser.add_argument("--connect", metavar="URL",
                        help="vehicle connection (sim://, udp:HOST:PORT, tcp:HOST:PORT, ...); "
                        "overrides vehicle.connection")
    parser.add_argument("--seed", type=types.seed,
                        help="overrides the mission's seed (0 .. 2**32-1)")
    parser.add_argument("--set", action="append", metavar="KEY=VALUE",
                        help="override a mission setting by its dotted name, e.g. "
                        "--set landing.verification_altitude=5 (repeatable)")
    parser.add_argument("--out", metavar="DIR", help="report directory (default out/MISSION)")
    parser.add_argument("--quiet", action="store_true",
                        help="no per-phase lines, only the outcome and the report path")
    parser.add_argument("--on-interrupt", choices=("land", "hold"), default="land",
                        help="live mode: what Ctrl-C does before exiting (default land); a "
                        "lockstep flight stops where it is. Either writes its report, marked "
                        "interrupted")
    parser.add_argument("--home-from", choices=("vehicle", "file"), default=None,
                        help="live mode, when the mission file's home and the vehicle's "
                        "differ by more than vehicle.home_tolerance (else the flight is "
                        "refused, exit 2): 'vehicle' flies lat/lon waypoints to their "
                        "lat/lon; 'file' flies the mission as drawn about the file's home, "
                        "moved to the vehicle's home (lat/lon waypoints are then NOT reached "
                        "at their lat/lon); overrides vehicle.home_from")
    parser.set_defaults(func=run)
