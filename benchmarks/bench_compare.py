"""Before/after speed of whole flights, measured in one run: benchmarks/bench_profile.py is run
alternately against an older checkout (``--before``, e.g. a ``git worktree`` of the commit
before a change) and this one, each in its own process with that checkout first on
PYTHONPATH, and the CPU per simulated second of every part is printed side by side with the
ratio. Alternating the two keeps a shared machine's load changes out of the ratios.

Run: .venv/bin/python benchmarks/bench_compare.py --before /path/to/old/checkout
     [--mission missions/mars_science.yaml] [--seeds 0 1] [--rounds 2] [--report]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
from _seeds import add_seed_arguments, chosen_seeds

ROOT = Path(__file__).resolve().parents[1]
PROFILE = Path(__file__).resolve().parent / "bench_profile.py"


def _profile(tree: Path, missions: list[str], seeds: list[int], report: bool) -> list[dict]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    command = [sys.executable, str(PROFILE), "--json", "--seeds", *map(str, seeds)]
    if report:
        command.append("--report")
    for mission in missions:
        command += ["--mission", mission]
    out = subprocess.run(command, env=env, cwd=tree, check=True, capture_output=True, text=True)
    return [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", required=True, type=Path, help="the older checkout")
    parser.add_argument("--mission", action="append", default=None)
    add_seed_arguments(parser)
    parser.add_argument("--rounds", type=int, default=1, help="alternations of the two")
    parser.add_argument("--report", action="store_true",
                        help="flights write their report directories, as campaign runs do")
    args = parser.parse_args(argv)
    args.seeds = chosen_seeds(args)
    missions = args.mission or [str(ROOT / "missions" / "mars_science.yaml"),
                                str(ROOT / "missions" / "demo.yaml")]
    missions = [str(Path(m).resolve()) for m in missions]
    trees = {"before": args.before.resolve(), "after": ROOT}
    totals: dict[str, dict[str, dict]] = {k: defaultdict(lambda: defaultdict(float))
                                          for k in trees}
    outcomes: dict[str, dict[str, list]] = {k: defaultdict(list) for k in trees}
    load = [os.getloadavg()[0]]
    for _ in range(args.rounds):
        for name, tree in trees.items():
            for row in _profile(tree, missions, args.seeds, args.report):
                acc = totals[name][row["mission"]]
                for key in ("sim", "cpu", "wall"):
                    acc[key] += row[key]
                for part, value in row["parts"].items():
                    acc["part:" + part] += value
                outcomes[name][row["mission"]].append(row["outcomes"])
            load.append(os.getloadavg()[0])
    print(f"machine: {os.cpu_count()} cores, 1-minute load average {min(load):.2f} .. "
          f"{max(load):.2f} during the run; before = {trees['before']}, after = {ROOT}")
    for mission in (Path(m).name for m in missions):
        b, a = totals["before"][mission], totals["after"][mission]
        same = outcomes["before"][mission] == outcomes["after"][mission]
        print(f"== {mission}: seeds {' '.join(map(str, args.seeds))} x {args.rounds} rounds, "
              f"{a['sim'] / args.rounds:.0f} simulated s per round; outcomes "
              f"{'the same' if same else 'DIFFERENT'}")
        print(f"  {'ms CPU per simulated s':<24}{'before':>9}{'after':>9}{'speed-up':>10}")
        parts = [k for k in b if k.startswith("part:")]
        for key in parts + ["cpu"]:
            label = key.removeprefix("part:") if key != "cpu" else "total"
            vb, va = b[key] / b["sim"] * 1e3, a[key] / a["sim"] * 1e3
            ratio = f"{vb / va:.2f}x" if va > 0 else "-"
            print(f"  {label:<24}{vb:>9.2f}{va:>9.2f}{ratio:>10}")
        print(f"  real time per core (CPU): before {b['sim'] / b['cpu']:.1f}x, "
              f"after {a['sim'] / a['cpu']:.1f}x; in wall time: before "
              f"{b['sim'] / b['wall']:.1f}x, after {a['sim'] / a['wall']:.1f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
