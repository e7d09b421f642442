"""``lander demo``: fly the demo mission (missions/mars_demo.yaml) on the embedded SITL and
show where its report is."""

from __future__ import annotations

import argparse
from pathlib import Path

from autonomy.errors import UserError

# The demo shows the product: terrain, the elevation-map detector in the loop, and a site
# that fails verification before the next one verifies (missions/demo.yaml is the quicker
# rehearsal with scripted sites over flat ground that many tests fly).
DEMO_MISSION = "mars_demo.yaml"


def mission_path(name: str) -> Path:
    """missions/NAME of the repository this package lives in (or of the cwd)."""
    for base in (Path(__file__).resolve().parents[2], Path.cwd()):
        path = base / "missions" / name
        if path.is_file():
            return path
    raise UserError(f"missions/{name} not found next to the package nor in the current "
                    "directory")


def demo_mission_path() -> Path:
    """The mission ``lander demo`` flies."""
    return mission_path(DEMO_MISSION)


def run(args: argparse.Namespace) -> int:
    from autonomy.cli.outdir import check_flight_folder, writing_into
    from autonomy.cli.validate import load_or_explain
    from autonomy.runner import fly

    path = demo_mission_path()
    mission = load_or_explain("demo", path)
    if mission is None:
        return 2
    out = Path(args.out)
    check_flight_folder(out)
    print(f"flying {path} on the embedded SITL (lockstep); report in {out}/")
    with writing_into(out, "the flight's report"):
        result = fly(mission, out_dir=out, console=True)
    print(what_happened(result.summary, mission.landing.verification_altitude))
    return result.exit_code


def what_happened(summary: dict, verification_altitude: float) -> str:
    """The demo's story in one line, from the flight's summary.json dict."""
    words = [f"the {summary.get('detector')} detector reported "
             f"{summary.get('sites_received', 0)} site observations over the "
             f"{summary.get('world')} world"]
    tried = summary.get("verification_attempts") or 0
    if tried:
        banned = summary.get("sites_banned") or 0
        words.append(f"{tried} {'site' if tried == 1 else 'sites'} checked from "
                     f"{verification_altitude:g} m above, {banned} failed verification and "
                     f"{'was' if banned == 1 else 'were'} banned")
    if summary.get("outcome") == "landed":
        words.append(f"landed {summary.get('touchdown_error') or 0:.2f} m from the verified "
                     "site, on ground the ground truth judged safe")
    else:
        words.append(f"outcome {summary.get('outcome')}")
    return "what happened: " + "; ".join(words)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo", help="fly the demo mission and print where its report is",
        description=f"Fly missions/{DEMO_MISSION} in lockstep on the embedded SITL: a survey "
        "over Mars terrain with the elevation-map detector in the loop, a site that fails "
        "verification at 2.5 m and is banned, and a landing on the next one. Writes the "
        "flight report (summary.json, events.jsonl, flight.tlog, report.png, report.html).",
    )
    parser.add_argument("--out", metavar="DIR", default="out/demo",
                        help="report directory (default out/demo)")
    parser.set_defaults(func=run)
