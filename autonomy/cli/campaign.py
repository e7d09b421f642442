"""``lander campaign``: Monte-Carlo campaigns of seeded lockstep flights.

    lander campaign MISSION.yaml --runs N [--seed S] [--vary KEY=SPEC ...]
                    [--workers K | --scheduler tcp://HOST:PORT | --scheduler local]
                    [--out DIR] [--retry-errors] [--quiet]
    lander campaign --compare A.yaml B.yaml ... --runs N [--seed S] [...]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from autonomy.campaign.store import RunLog
from autonomy.cli import args as types
from autonomy.errors import UserError

VARY_HELP = (
    "vary a mission key: KEY=V1,V2,... (a list), KEY=A:B (the integers A..B) or KEY=A:B:N "
    "(N values evenly from A to B); repeat for a cartesian product of variants"
)


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "campaign",
        help="fly many seeded simulated flights and summarise the landing outcomes",
        description=(
            "Fly N lockstep flights of a mission per variant, each with its own seed derived "
            "from --seed, on a local process pool or a Dask cluster. Finished runs are "
            "appended to DIR/runs.jsonl at once; re-running the same command skips them. "
            "Writes DIR/summary.json, DIR/campaign.png and DIR/campaign.html (each run linked "
            "to its flight page in DIR/runs/) and prints the summary table. A run whose "
            "worker process dies (out of memory, a crash) is flown once more alone; if it "
            "dies again it is recorded as an error naming the signal, the command exits 1, "
            "and re-running it flies that run again."
        ),
    )
    parser.add_argument("mission", nargs="?", metavar="MISSION.yaml", help="mission file")
    parser.add_argument("--runs", type=types.integer(1, 100_000), required=True, metavar="N",
                        help="flights per variant (per mission with --compare)")
    parser.add_argument("--seed", type=types.seed, default=0, metavar="S",
                        help="campaign seed; run i flies with SeedSequence(S).spawn()[i] "
                        "(default 0)")
    parser.add_argument("--vary", action="append", default=[], metavar="KEY=SPEC",
                        help=VARY_HELP)
    parser.add_argument("--workers", type=types.integer(1, 1024), default=None, metavar="K",
                        help="worker processes (default: one per core)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="run on Dask: tcp://HOST:PORT of a running scheduler, or 'local' "
                        "for a LocalCluster on 127.0.0.1 (needs the 'cluster' extra)")
    parser.add_argument("--connect-timeout", type=types.number(0, 3600, low_open=True),
                        default=10.0, metavar="SECONDS",
                        help="how long to wait for the --scheduler (default 10)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="output directory (default campaigns/<mission name>)")
    parser.add_argument("--compare", nargs="+", default=None, metavar="MISSION.yaml",
                        help="fly the same seeds through each mission file and compare "
                        "success rates against the first")
    parser.add_argument("--retry-errors", action="store_true",
                        help="fly again runs recorded as errors (default: skip every "
                        "recorded run)")
    parser.add_argument("--quiet", action="store_true", help="no progress line")
    parser.add_argument("--no-pages", action="store_true",
                        help="do not write each run's report folder (DIR/runs/RUN/report.html "
                        "and its logs, which campaign.html links to)")
    parser.set_defaults(func=run)


def _names(paths: list[str]) -> list[str]:
    """Directory names for the missions of --compare: file stems, made unique."""
    names: list[str] = []
    for path in paths:
        stem = Path(path).stem or "mission"
        name, k = stem, 2
        while name in names:
            name, k = f"{stem}-{k}", k + 1
        names.append(name)
    return names


@contextmanager
def _resumable(out: Path) -> Iterator[None]:
    """On Ctrl-C, say what is kept and how to go on before the CLI's "interrupted" line."""
    try:
        yield
    except KeyboardInterrupt:
        logs = sorted(out.glob("**/runs.jsonl"))
        kept = sum(len(RunLog(log.parent).load()) for log in logs)
        print(f"{kept} finished run(s) kept in {', '.join(map(str, logs)) or out}; the same "
              "command flies the rest", file=sys.stderr)
        raise


def _report_died(results: list) -> int:
    """Name each run whose worker process died, on stderr; 1 if any did, else 0."""
    died = [r for result in results for r in result.died()]
    for record in died:
        print(f"run {record['run_id']} (seed {record['seed']}) failed: its "
              f"{record['error']}; the same command flies it again", file=sys.stderr)
    return 1 if died else 0


def run(args: argparse.Namespace) -> int:
    from autonomy.campaign import compare_campaigns, run_campaign
    from autonomy.cli.outdir import check_campaign_folder, writing_into
    from autonomy.config import load_mission

    if args.compare is not None:
        if args.mission is not None:
            raise UserError("give either MISSION.yaml or --compare A.yaml B.yaml ..., not both")
        if args.vary:
            raise UserError("--vary cannot be combined with --compare")
        if len(args.compare) < 2:
            raise UserError("--compare: needs at least two mission files")
        names = _names(args.compare)
        missions = [(name, load_mission(path)) for name, path in zip(names, args.compare,
                                                                     strict=True)]
        out = args.out or str(Path("campaigns") / ("compare-" + "-vs-".join(names)))
        for name in names:
            check_campaign_folder(Path(out) / name, "--out folder")
        with writing_into(Path(out), "the campaigns' results"), _resumable(Path(out)):
            result = compare_campaigns(
                missions, runs=args.runs, out_dir=out, seed=args.seed, workers=args.workers,
                scheduler=args.scheduler, connect_timeout=args.connect_timeout,
                retry_errors=args.retry_errors, quiet=args.quiet, pages=not args.no_pages,
            )
        for name, campaign in zip(names, result.campaigns, strict=True):
            print(f"{name}:")
            print(campaign.table())
            if campaign.throughput_line():
                print(campaign.throughput_line())
            print()
        print(result.table())
        print(f"wrote {result.out_dir}/compare.json and one directory per mission")
        return _report_died(result.campaigns)
    if args.mission is None:
        raise UserError("a mission file is required (or --compare A.yaml B.yaml ...)")
    mission = load_mission(args.mission)
    out = args.out or str(Path("campaigns") / (Path(args.mission).stem or "mission"))
    check_campaign_folder(Path(out))
    with writing_into(Path(out), "the campaign's results"), _resumable(Path(out)):
        result = run_campaign(
            mission, runs=args.runs, out_dir=out, seed=args.seed, vary=args.vary,
            workers=args.workers, scheduler=args.scheduler,
            connect_timeout=args.connect_timeout, retry_errors=args.retry_errors,
            quiet=args.quiet, name=Path(args.mission).stem, pages=not args.no_pages,
        )
    print(result.table())
    errors = sum(row["error"] for row in result.rows)
    note = f"; {errors} run(s) raised, see 'error' in runs.jsonl" if errors else ""
    print(f"flew {result.flown} run(s), {result.skipped} already recorded{note}")
    if result.throughput_line():
        print(result.throughput_line())
    print(f"wrote {result.out_dir}/runs.jsonl, summary.json, campaign.png, campaign.html "
          f"(lander replay {result.out_dir})")
    return _report_died([result])
