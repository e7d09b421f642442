"""A campaign run's report directory, byte for byte, before and after a change.

Flies FLIGHTS as a campaign run does (:func:`autonomy.campaign.worker.fly_with_page`:
summary.json, events.jsonl, flight.tlog, tree.btlog, blackboard.jsonl, report.html) with an
older checkout and with this one, and compares every file of each run's directory byte for
byte, the wall-clock figures (``wall_time``, ``realtime_factor``, in summary.json and in the
summary report.html embeds) aside::

    python tests/speed/report_dirs.py --before ../other-checkout   # flies both, compares
    python tests/speed/report_dirs.py --write DIR                  # this checkout's dirs
    python tests/speed/report_dirs.py --compare DIR_A DIR_B        # two written sets

Prints ``same`` or the differing files per run; exits 1 if any file differs.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# (mission file under missions/, seed): a campaign's first Mars run, a golden Mars flight
# and the demo.
FLIGHTS = [("mars_science.yaml", 3757552657), ("mars_science.yaml", 1), ("demo.yaml", 0)]

# What measures the computer, not the flight.
_WALL = re.compile(rb'"(wall_time|realtime_factor)": ?[-+0-9.eE]+')


def write(out: Path) -> None:
    """Fly FLIGHTS into ``out/<mission>-<seed>`` with the checkout on sys.path."""
    from autonomy.campaign.worker import fly_with_page
    from autonomy.config import load_mission

    for mission, seed in FLIGHTS:
        run = out / f"{Path(mission).stem}-{seed}"
        run.mkdir(parents=True, exist_ok=True)
        fly_with_page(load_mission(ROOT / "missions" / mission), seed, run)


def _masked(path: Path) -> bytes:
    return _WALL.sub(rb'"\1":WALL', path.read_bytes())


def compare(before: Path, after: Path) -> bool:
    """Print per run whether every file is the same; True if all are."""
    same = True
    for mission, seed in FLIGHTS:
        name = f"{Path(mission).stem}-{seed}"
        a, b = before / name, after / name
        files_a = sorted(p.name for p in a.iterdir()) if a.is_dir() else []
        files_b = sorted(p.name for p in b.iterdir()) if b.is_dir() else []
        if not files_a or files_a != files_b:
            print(f"{name}: files differ: {files_a} / {files_b}")
            same = False
            continue
        differ = [f for f in files_a if _masked(a / f) != _masked(b / f)]
        print(f"{name}: " + (f"DIFFERENT {', '.join(differ)}" if differ
                             else f"same ({len(files_a)} files)"))
        same = same and not differ
    return same


def _write_with(checkout: Path, out: Path) -> None:
    """Fly FLIGHTS with ``checkout``'s packages (this script, and the missions, from here)."""
    env = dict(os.environ, PYTHONPATH=str(checkout.resolve()))
    subprocess.run([sys.executable, __file__, "--write", str(out)], env=env, check=True)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--before", type=Path, help="an older checkout to compare with")
    group.add_argument("--write", type=Path, metavar="DIR", help="write this checkout's")
    group.add_argument("--compare", type=Path, nargs=2, metavar=("A", "B"))
    args = parser.parse_args()
    if args.write is not None:
        write(args.write)
        return 0
    if args.compare is not None:
        return 0 if compare(*args.compare) else 1
    with tempfile.TemporaryDirectory() as tmp:
        before, after = Path(tmp, "before"), Path(tmp, "after")
        _write_with(args.before, before)
        _write_with(ROOT, after)
        return 0 if compare(before, after) else 1


if __name__ == "__main__":
    sys.exit(main())
