"""What the replay benchmarks (bench_elevation.py, bench_render.py) share: running a script's
``--replay FILE`` child process alternately in an older checkout and this one, and printing
a figure per checkout side by side with the speed-up."""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)

ROOT = Path(__file__).resolve().parents[1]


def replay_arguments(description: str) -> argparse.ArgumentParser:
    """The options every replay benchmark takes: mission, seed, rounds, the older checkout,
    and the hidden ``--replay FILE`` of the child process."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--mission", type=Path, default=ROOT / "missions" / "mars_science.yaml")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--before", type=Path, default=None, help="an older checkout")
    parser.add_argument("--replay", type=Path, default=None, help=argparse.SUPPRESS)
    return parser


def timed(fn: Callable, spent: Callable[[float], None]) -> Callable:
    """``fn`` reporting the CPU milliseconds of the calling thread each call took to
    ``spent``."""
    def call(*args, **kwargs):
        start = time.thread_time()
        try:
            return fn(*args, **kwargs)
        finally:
            spent(1e3 * (time.thread_time() - start))
    return call


def replay_alternately(script: str, data: Path, before: Path | None,
                       rounds: int) -> dict[str, list[dict]]:
    """``{"before": [...], "after": [...]}`` (only "after" without ``before``): the JSON
    each ``python script --replay data`` printed last, one per round, the checkouts taking
    turns, each first on PYTHONPATH and the working directory."""
    trees = {"after": ROOT} if before is None else {"before": before.resolve(), "after": ROOT}
    results: dict[str, list[dict]] = defaultdict(list)
    for _ in range(rounds):
        for name, tree in trees.items():
            env = dict(os.environ, PYTHONPATH=str(tree))
            out = subprocess.run([sys.executable, str(Path(script).resolve()), "--replay",
                                  str(data)], env=env, cwd=tree, capture_output=True,
                                 text=True, check=True)
            results[name].append(json.loads(out.stdout.strip().splitlines()[-1]))
    return dict(results)


def print_header(title: str, names: list[str]) -> None:
    """The column heads of :func:`print_row`'s table."""
    header = "".join(f"{name:>10s}" for name in names)
    print(f"  {title:46s} {header}" + ("   speed-up" if len(names) == 2 else ""))


def print_row(label: str, values: list[float]) -> None:
    """One figure per checkout, and before / after when there are two."""
    cells = "".join(f"{v:10.2f}" for v in values)
    ratio = f"{values[0] / values[1]:10.2f}x" if len(values) == 2 and values[1] else ""
    print(f"  {label:46s} {cells} {ratio}")
