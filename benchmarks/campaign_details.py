"""Per-variant details of a finished campaign that its summary table leaves out, counted from
its ``runs.jsonl``: landing tries, touchdown error and the battery left.

    .venv/bin/python benchmarks/campaign_details.py campaigns/mars_verification/runs.jsonl
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
import numpy as np


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", type=Path, help="a campaign's runs.jsonl")
    args = parser.parse_args()
    try:
        lines = args.runs.read_text().splitlines()
        records = [json.loads(line) for line in lines if line.strip()]
    except (OSError, json.JSONDecodeError) as exc:
        print(f"campaign_details: {args.runs}: {exc}", file=sys.stderr)
        return 2
    variants: dict[str, list[dict]] = defaultdict(list)
    for record in records:
        variants[record.get("variant_label") or "-"].append(record)
    for label, runs in variants.items():
        landed = [r for r in runs if r.get("outcome") == "landed"]
        tries = np.array([r.get("verification_attempts") or 0 for r in runs])
        print(f"{label}: {len(runs)} runs, {len(landed)} landed safe")
        if tries.any():
            first = sum(1 for r in landed if r.get("verification_attempts") == 1)
            print(f"  landing tries: mean {tries.mean():.1f}, most {tries.max()}; "
                  f"{first} landed on the first site tried")
        error = np.array([r["touchdown_error"] for r in runs
                          if r.get("touchdown_error") is not None])
        if len(error):
            print(f"  touchdown from the chosen site: median {np.median(error):.2f} m, "
                  f"90th percentile {np.percentile(error, 90):.2f} m, largest {error.max():.2f} m")
        used = [r["battery_used"] for r in runs if r.get("battery_used") is not None]
        if used:
            print(f"  battery left: at least {100.0 - max(used):.1f} %")
    return 0


if __name__ == "__main__":
    sys.exit(main())
