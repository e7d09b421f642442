"""``lander demo``: fly missions/demo.yaml on the embedded SITL and show the report."""

from __future__ import annotations

import argparse
from pathlib import Path

from autonomy.errors import UserError


def demo_mission_path() -> Path:
    """missions/demo.yaml of the repository this package lives in (or of the cwd)."""
    for base in (Path(__file__).resolve().parents[2], Path.cwd()):
        path = base / "missions" / "demo.yaml"
        if path.is_file():
            return path
    raise UserError("missions/demo.yaml not found next to the package nor in the current "
                    "directory")


def run(args: argparse.Namespace) -> int:
    from autonomy.cli.validate import load_or_explain
    from autonomy.runner import fly

    path = demo_mission_path()
    mission = load_or_explain("demo", path)
    if mission is None:
        return 2
    out = Path(args.out)
    print(f"flying {path} on the embedded SITL (lockstep); report in {out}/")
    result = fly(mission, out_dir=out, console=True)
    return result.exit_code


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "demo", help="fly the demo mission and print where its report is",
        description="Fly missions/demo.yaml in lockstep on the embedded SITL and write the "
        "flight report (summary.json, events.jsonl, flight.tlog, report.png).",
    )
    parser.add_argument("--out", metavar="DIR", default="out/demo",
                        help="report directory (default out/demo)")
    parser.set_defaults(func=run)
