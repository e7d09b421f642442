"""What a flight's outcome is, for the before/after comparison of the speed work (issue 21):
everything in summary.json but the wall-clock figures and the link's message counts, every
event but the tree's own status changes (those belong to the tree's structure, which may be
rewritten while flights stay tick-identical), and the Landing Site Manager's final sites
with all their fields.

``python tests/speed/golden.py --write`` records the flights listed in GOLDEN_FLIGHTS with
the code checked out into tests/speed/data/golden_flights.json; without ``--write`` it flies
them again and reports any difference (what tests/speed/test_outcome_equality.py does for a
short subset).
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data" / "golden_flights.json"

# (mission file under missions/, seed) of every recorded flight.
GOLDEN_FLIGHTS = [
    ("mars_science.yaml", 0),
    ("mars_science.yaml", 1),
    ("mars_science.yaml", 2),
    ("mars_science.yaml", 7),
    ("demo.yaml", 0),
    ("demo.yaml", 1),
]

# Summary fields that measure the computer, not the flight, and the link's message counts
# (they change when the driver asks for another telemetry stream, e.g. for the log
# viewers, while the flight stays the same).
WALL_FIELDS = ("wall_time", "realtime_factor", "link")


LIBRARIES = Path(__file__).resolve().parent / "data" / "libraries.json"


def libraries() -> dict[str, str]:
    """Versions of what decides the last bits of a flight (the numerical libraries and
    Python): recordings compare bit for bit only under the versions they were made with."""
    import platform

    import cv2
    import numpy
    import scipy

    return {"python": ".".join(platform.python_version_tuple()[:2]), "numpy": numpy.__version__,
            "scipy": scipy.__version__, "opencv": cv2.__version__}


def recorded_with() -> dict[str, str]:
    return json.loads(LIBRARIES.read_text())


def write_libraries() -> None:
    LIBRARIES.write_text(json.dumps(libraries(), indent=1) + "\n")


def _digest(value: Any) -> str:
    text = json.dumps(value, sort_keys=True, separators=(",", ":"), default=repr)
    return hashlib.sha256(text.encode()).hexdigest()


def flight_record(result: Any) -> dict[str, Any]:
    """The outcome of a :class:`autonomy.runner.FlightResult` as a JSON-able dict."""
    summary = {k: v for k, v in result.summary.items() if k not in WALL_FIELDS}
    events = [e for e in result.events if e.get("kind") != "tree"]
    sites = json.loads(json.dumps([dataclasses.asdict(site) for site in result.data.sites]))
    return {
        "summary": summary,
        "events": len(events),
        "events_sha256": _digest(events),
        "sites": len(sites),
        "sites_sha256": _digest(sites),
        "best_sites": sites[:3],  # to see what changed when the digest differs
    }


def fly_record(mission_file: str, seed: int) -> dict[str, Any]:
    from autonomy.config import load_mission
    from autonomy.runner import fly

    return flight_record(fly(load_mission(ROOT / "missions" / mission_file), seed=seed))


def load() -> dict[str, dict[str, Any]]:
    return json.loads(DATA.read_text())


def key(mission_file: str, seed: int) -> str:
    return f"{mission_file}:{seed}"


# Perception counters of pixels the depth camera no longer renders because no point of
# theirs can land in the elevation map (issue 21, lever A): the points that do land there,
# and so every map, site and event, stay the same bit for bit. Pixels dropped as unusable
# can only become fewer (unrendered pixels are not dropped: they were never measured).
UNRENDERED_COUNTERS = ("pixels_not_rendered", "points_outside_map")
DROPPED_PREFIX = "pixels_dropped_"


def _perception_differences(a: dict[str, Any], b: dict[str, Any]) -> list[str]:
    out = []
    for name in sorted(set(a) | set(b)):
        x, y = a.get(name), b.get(name)
        if name in UNRENDERED_COUNTERS or (name not in a and y in (0, None)):
            continue
        if name.startswith(DROPPED_PREFIX) and x is not None and y is not None and y <= x:
            continue
        if x != y:
            out.append(f"summary.perception.{name}: {x!r} -> {y!r}")
    return out


def differences(expected: dict[str, Any], got: dict[str, Any]) -> list[str]:
    """Human-readable differences between two flight records (empty when equal): bit for
    bit but for the perception counters of unrendered pixels (see UNRENDERED_COUNTERS)."""
    out = []
    for name in sorted(set(expected["summary"]) | set(got["summary"])):
        a, b = expected["summary"].get(name), got["summary"].get(name)
        if name not in expected["summary"] and b in (0, None):
            continue  # a field added after the recording, reporting that nothing happened
        if name == "perception" and isinstance(a, dict) and isinstance(b, dict):
            out += _perception_differences(a, b)
        elif a != b:
            out.append(f"summary.{name}: {a!r} -> {b!r}")
    for name in ("events", "events_sha256", "sites", "sites_sha256"):
        if expected[name] != got[name]:
            out.append(f"{name}: {expected[name]} -> {got[name]}")
    if json.dumps(expected["best_sites"], sort_keys=True) != json.dumps(
        got["best_sites"], sort_keys=True
    ):  # NaN-safe
        out.append(f"best sites: {expected['best_sites']} -> {got['best_sites']}")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="record instead of compare")
    parser.add_argument("--only", default=None, help="mission file to restrict to")
    args = parser.parse_args(argv)
    flights = [f for f in GOLDEN_FLIGHTS if args.only in (None, f[0])]
    if args.write:
        records = {key(m, s): fly_record(m, s) for m, s in flights}
        DATA.parent.mkdir(parents=True, exist_ok=True)
        old = load() if DATA.exists() else {}
        old.update(records)
        DATA.write_text(json.dumps(old, indent=1, sort_keys=True) + "\n")
        write_libraries()
        print(f"recorded {len(records)} flights in {DATA}")
        return 0
    golden = load()
    bad = 0
    for mission_file, seed in flights:
        diff = differences(golden[key(mission_file, seed)], fly_record(mission_file, seed))
        print(f"{mission_file} seed {seed}: {'same' if not diff else 'DIFFERENT'}", flush=True)
        for line in diff:
            print(f"  {line}")
        bad += bool(diff)
    return 1 if bad else 0


if __name__ == "__main__":
    # As a script: this checkout's packages ahead of the environment's editable install
    # (which may point at another checkout), unless the caller chose them by PYTHONPATH.
    if not os.environ.get("PYTHONPATH"):
        sys.path.insert(0, str(ROOT))
    sys.exit(main())
