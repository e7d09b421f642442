"""The long fuzz run: at least 10,000 generated inputs through every entry point of `lander`.

The strategies and the checks are those of tests/fuzz (tests/fuzz/harness.py): mission
documents generated from the schema and mutated from missions/, argument lists of every
subcommand, corrupt detector inputs and elevation files. Each case must end with exit 0, 1
or 2, raise nothing, print one clear line per problem and answer within its deadline (a
hang). Prints, per entry point, the cases tried, tracebacks, hangs and other failures, the
median and slowest case, and the first failures in full.

    .venv/bin/python benchmarks/bench_fuzz.py                # 10,000+ inputs
    .venv/bin/python benchmarks/bench_fuzz.py --scale 0.1    # a tenth of each
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import statistics
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

from _checkout import ROOT  # noqa: E402  (this checkout's packages first)


def _harness():
    spec = importlib.util.spec_from_file_location("harness", ROOT / "tests/fuzz/harness.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["harness"] = module
    spec.loader.exec_module(module)
    return module


# Inputs per family at --scale 1 (10,600 in all).
PLAN = (
    ("validate", "schema", 3000),
    ("validate", "mutated", 3000),
    ("fly", None, 250),
    ("cli", "quick", 2000),
    ("cli", "flying", 150),
    ("detect", None, 1600),
    ("world", None, 600),
)


def _explorer(draw, record):
    """A test body for @given that records each case and never fails (so hypothesis goes on
    generating instead of shrinking)."""

    def explore(data) -> None:
        record(draw(data))

    return explore


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scale", type=float, default=1.0, help="times the default counts")
    parser.add_argument("--seed", type=int, default=2026, help="hypothesis seed")
    parser.add_argument("--show", type=int, default=5, help="failures printed in full")
    parser.add_argument("--families", default=None, metavar="LIST",
                        help="only these families, comma-separated, from: " + ", ".join(
                            sorted({f if v is None else f"{f}:{v}" for f, v, _ in PLAN})))
    args = parser.parse_args()
    plan = PLAN
    if args.families:
        wanted = {name.strip() for name in args.families.split(",") if name.strip()}
        plan = tuple(row for row in PLAN
                     if (row[0] if row[1] is None else f"{row[0]}:{row[1]}") in wanted
                     or row[0] in wanted)
        if not plan:
            parser.error(f"--families: none of {sorted(wanted)} is a family")

    harness = _harness()
    from hypothesis import HealthCheck, Phase, given, seed, settings
    from hypothesis import strategies as st

    workdir = Path(tempfile.mkdtemp(prefix="bench_fuzz_"))
    files = harness.Files(workdir)
    runner = harness.Runner(workdir, deadline=120.0)
    port = harness.closed_port()
    stats: dict[str, dict] = defaultdict(lambda: {"tried": 0, "traceback": 0, "hang": 0,
                                                  "other": 0, "seconds": [], "codes": {}})
    failures: list = []
    start = time.perf_counter()
    total_planned = sum(max(1, int(n * args.scale)) for *_, n in plan)
    done = [0]

    def record(case) -> None:
        result = harness.run_case(runner, files, case)
        row = stats[case.entry]
        row["tried"] += 1
        row["seconds"].append(result.seconds)
        row["codes"][result.code] = row["codes"].get(result.code, 0) + 1
        kind = result.kind()
        if kind is not None:
            row[kind] += 1
            failures.append(result)
        done[0] += 1
        elapsed = time.perf_counter() - start
        if sys.stderr.isatty():
            sys.stderr.write(f"\rfuzz: {done[0]}/{total_planned} inputs, {len(failures)} "
                             f"failing, {elapsed:.0f} s\x1b[K")
            sys.stderr.flush()
        elif done[0] % 500 == 0:  # a log file gets a line now and then
            print(f"fuzz: {done[0]}/{total_planned} inputs, {len(failures)} failing, "
                  f"{elapsed:.0f} s", file=sys.stderr, flush=True)

    def strategy_for(family: str, variant: str | None):
        if family == "validate":
            return lambda data: data.draw(harness.validate_cases(files, variant))
        if family == "fly":
            return lambda data: data.draw(harness.fly_cases(files))
        if family == "cli":
            commands = (["validate", "tree", "sitl", "link", "detect", "replay"]
                        if variant == "quick"
                        else ["fly", "campaign", "terrain", "demo"])
            return lambda data: data.draw(
                harness.cli_cases(files, port, data.draw(st.sampled_from(commands))))
        if family == "detect":
            return lambda data: data.draw(harness.detect_cases(files))
        return lambda data: data.draw(harness.world_file_cases(files))

    try:
        for i, (family, variant, count) in enumerate(PLAN):
            if (family, variant, count) not in plan:
                continue
            n = max(1, int(count * args.scale))
            explore = _explorer(strategy_for(family, variant), record)
            seed(args.seed + i)(settings(
                max_examples=n, deadline=None, database=None, phases=[Phase.generate],
                suppress_health_check=list(HealthCheck),
            )(given(data=st.data())(explore)))()
    finally:
        runner.close()
        if sys.stderr.isatty():
            sys.stderr.write("\r\x1b[K")
    wall = time.perf_counter() - start

    print(f"fuzz run: {sum(r['tried'] for r in stats.values()):,} inputs in {wall:.0f} s "
          f"(machine: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f}); hypothesis seed "
          f"{args.seed}; deadline 120 s a case (180 s for flights)")
    print(f"{'entry point':<36}{'tried':>7}{'tracebacks':>12}{'hangs':>7}{'other':>7}"
          f"{'median s':>10}{'max s':>8}  exit codes")
    for entry in sorted(stats):
        row = stats[entry]
        codes = ", ".join(f"{c}: {n}" for c, n in sorted(row["codes"].items(),
                                                         key=lambda kv: str(kv[0])))
        print(f"{entry:<36}{row['tried']:>7}{row['traceback']:>12}{row['hang']:>7}"
              f"{row['other']:>7}{statistics.median(row['seconds']):>10.3f}"
              f"{max(row['seconds']):>8.1f}  {codes}")
    totals = {k: sum(r[k] for r in stats.values()) for k in ("tried", "traceback", "hang",
                                                             "other")}
    print(f"{'total':<36}{totals['tried']:>7}{totals['traceback']:>12}{totals['hang']:>7}"
          f"{totals['other']:>7}")
    for result in failures[: args.show]:
        print("\nFAILED: " + result.describe())
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
