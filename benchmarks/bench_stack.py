"""CPU per simulated second of whole lockstep flights with nothing timing their parts.

benchmarks/bench_profile.py wraps every part's entry point in a CPU-time reading: on the
demo (no perception) that is some eight clock reads and four extra calls per tick, a sizeable
part of a tick that costs a few hundred microseconds, and its first flight also pays the
process's one-time costs (the lazy imports). This script flies one warm-up flight, then
``--rounds`` rounds of the seeds with nothing wrapped, and prints the CPU (this thread's) per
simulated second of each round's flights: the minimum (the figure least disturbed by other
load on a shared machine) and the median, and the speed in real time per core.

With ``--before DIR`` it runs itself for an older checkout and this one alternately, each in
its own process with that checkout first on PYTHONPATH, and prints both with the ratio.

Run: .venv/bin/python benchmarks/bench_stack.py [--mission missions/demo.yaml]
     [--seeds 0 1] [--rounds 5] [--before /path/to/old/checkout [--alternations 3]]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
from _seeds import add_seed_arguments, chosen_seeds

ROOT = Path(__file__).resolve().parents[1]


def measure(mission_path: str, seeds: list[int], rounds: int) -> dict:
    """{"sim": simulated s per round, "rounds": [ms CPU per simulated s, ...], "outcomes"}."""
    from autonomy.config import load_mission
    from autonomy.runner import fly

    mission = load_mission(mission_path)
    fly(mission, seed=seeds[0])  # warm-up: imports, caches, compiled kernels
    per_round, outcomes, sim = [], [], 0.0
    for _ in range(rounds):
        sim, cpu = 0.0, 0.0
        outcomes = []
        for seed in seeds:
            start = time.thread_time()
            result = fly(mission, seed=seed)
            cpu += time.thread_time() - start
            sim += float(result.summary["mission_time"])
            outcomes.append(f"{seed}:{result.outcome}")
        per_round.append(cpu / sim * 1e3)
    return {"sim": sim, "rounds": per_round, "outcomes": outcomes}


def _line(label: str, rounds: list[float]) -> str:
    best, median = min(rounds), statistics.median(rounds)
    return (f"  {label:<8} min {best:6.3f}  median {median:6.3f} ms CPU per simulated s  "
            f"({1e3 / best:.0f}x real time per core at the minimum)")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", default=str(ROOT / "missions" / "demo.yaml"))
    add_seed_arguments(parser)
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--before", type=Path, default=None, help="an older checkout")
    parser.add_argument("--alternations", type=int, default=3,
                        help="with --before: processes per checkout, alternating")
    parser.add_argument("--json", action="store_true", help="one JSON line (no --before)")
    args = parser.parse_args(argv)
    args.seeds = chosen_seeds(args)
    mission = str(Path(args.mission).resolve())
    if args.before is None:
        row = measure(mission, args.seeds, args.rounds)
        if args.json:
            print(json.dumps(row))
            return 0
        print(f"machine: {os.cpu_count()} cores, load average "
              f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")
        print(f"== {Path(mission).name}: seeds {' '.join(map(str, args.seeds))}, "
              f"{row['sim']:.0f} simulated s per round, {args.rounds} rounds after a warm-up "
              f"flight ({', '.join(row['outcomes'])})")
        print(_line("", row["rounds"]))
        return 0
    trees = {"before": args.before.resolve(), "after": ROOT}
    rounds: dict[str, list[float]] = {name: [] for name in trees}
    outcomes: dict[str, list] = {name: [] for name in trees}
    load = [os.getloadavg()[0]]
    for _ in range(args.alternations):
        for name, tree in trees.items():
            command = [sys.executable, str(Path(__file__).resolve()), "--json", "--mission",
                       mission, "--rounds", str(args.rounds), "--seeds",
                       *map(str, args.seeds)]
            env = dict(os.environ, PYTHONPATH=str(tree))
            out = subprocess.run(command, env=env, cwd=tree, check=True, capture_output=True,
                                 text=True)
            row = json.loads(out.stdout.strip().splitlines()[-1])
            rounds[name] += row["rounds"]
            outcomes[name].append(row["outcomes"])
            load.append(os.getloadavg()[0])
    same = outcomes["before"] == outcomes["after"]
    print(f"machine: {os.cpu_count()} cores, 1-minute load average {min(load):.2f} .. "
          f"{max(load):.2f}; before = {trees['before']}, after = {ROOT}")
    print(f"== {Path(mission).name}: seeds {' '.join(map(str, args.seeds))}, "
          f"{args.alternations} x {args.rounds} rounds each; outcomes "
          f"{'the same' if same else 'DIFFERENT'}")
    print(_line("before", rounds["before"]))
    print(_line("after", rounds["after"]))
    print(f"  speed-up {min(rounds['before']) / min(rounds['after']):.2f}x at the minimum, "
          f"{statistics.median(rounds['before']) / statistics.median(rounds['after']):.2f}x "
          "at the median")
    return 0


if __name__ == "__main__":
    sys.exit(main())
