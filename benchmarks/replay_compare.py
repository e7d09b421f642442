"""What the replay benchmarks (bench_elevation.py, bench_render.py) share: running a script's
``--replay FILE`` child process alternately in an older checkout and this one, and printing
a figure per checkout side by side with the speed-up."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


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
