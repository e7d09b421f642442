"""Compare two campaigns flown on the same seeds, run by run (issue 21: a speed change may
not change outcomes).

``python tests/speed/campaigns.py BEFORE_DIR AFTER_DIR`` reads each directory's runs.jsonl
(``lander campaign ... --out DIR``) and prints, for the runs both hold, how many have the
same outcome, touchdown, landing site tries and detector output within the tolerances below,
and every run that differs. Exit status 1 when any outcome differs.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

# Touchdowns closer than this (m) are the same touchdown (the same site, centred on again).
TOUCHDOWN_TOLERANCE = 0.01
# Counts (observations received, mission time, battery) may differ by this fraction.
RELATIVE_TOLERANCE = 0.01
EXACT_FIELDS = ("outcome", "stop_reason", "touchdown_safe", "sites_verified",
                "sites_banned", "verification_attempts", "search_patterns", "collisions")
RELATIVE_FIELDS = ("sites_received", "mission_time", "battery_used", "distance")


def load(directory: Path) -> dict[int, dict]:
    """Runs of a campaign directory by seed index (errors left out)."""
    runs = {}
    for line in (directory / "runs.jsonl").read_text().splitlines():
        run = json.loads(line)
        if run.get("error") is None:
            runs[int(run["seed_index"])] = run
    return runs


def run_differences(a: dict, b: dict) -> list[str]:
    """What differs between two runs of one seed beyond the tolerances."""
    out = []
    for name in EXACT_FIELDS:
        if a.get(name) != b.get(name):
            out.append(f"{name}: {a.get(name)!r} -> {b.get(name)!r}")
    ta, tb = a.get("touchdown"), b.get("touchdown")
    if (ta is None) != (tb is None):
        out.append(f"touchdown: {ta} -> {tb}")
    elif ta is not None and math.dist(ta, tb) > TOUCHDOWN_TOLERANCE:
        out.append(f"touchdown: {ta} -> {tb} ({math.dist(ta, tb):.3f} m)")
    for name in RELATIVE_FIELDS:
        x, y = a.get(name), b.get(name)
        if x is None or y is None:
            if x != y:
                out.append(f"{name}: {x!r} -> {y!r}")
        elif abs(y - x) > RELATIVE_TOLERANCE * max(abs(x), 1e-9):
            out.append(f"{name}: {x} -> {y}")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    args = parser.parse_args(argv)
    before, after = load(args.before), load(args.after)
    common = sorted(set(before) & set(after))
    exact = sum(before[i] == {**after[i], "wall_time": before[i]["wall_time"],
                              "worker": before[i]["worker"]} for i in common)
    changed = {i: run_differences(before[i], after[i]) for i in common}
    changed = {i: d for i, d in changed.items() if d}
    outcomes = sum(before[i]["outcome"] != after[i]["outcome"] for i in common)
    print(f"{len(common)} runs on the same seeds: {exact} identical in every field but the "
          f"wall time, {len(common) - len(changed)} within the tolerances "
          f"(touchdown {TOUCHDOWN_TOLERANCE} m, counts {RELATIVE_TOLERANCE:.0%}), "
          f"{outcomes} outcomes changed")
    for i, lines in changed.items():
        print(f"  seed index {i}: " + "; ".join(lines))
    return 1 if outcomes else 0


if __name__ == "__main__":
    sys.exit(main())
