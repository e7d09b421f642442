"""Where a simulated second of a lockstep flight goes, part by part.

Flies whole missions end to end with :func:`autonomy.runner.fly` (no report files) and times
each part of the loop by wrapping its entry point: world generation, the depth render, the
elevation-map update (fusion), the detection (map analysis), the Landing Site Manager, the
behaviour tree (its tick, including the commands it sends), the MAVLink driver (poll and
decode) and the embedded SITL (physics and telemetry). "other" is what is left of the
flight (event log, trace, setup). Each part is timed in this thread's CPU time
(``time.thread_time``), which other processes on a shared machine do not inflate; the wall
time is printed beside it.

Prints, per mission, milliseconds of CPU per simulated second for every part and how many
times faster than real time the flight runs per core (simulated time / CPU time).

With ``--report`` each flight also writes its report directory (events.jsonl, flight.tlog,
tree.btlog, blackboard.jsonl, report.html) into a temporary folder, as a campaign run does.

With ``--by-phase`` it prints a second table: each mission phase's simulated seconds (ticks
over the tick rate) and the CPU of its ticks, split into render, map update, detection and
the rest of the tick, so a change can be judged by where in a flight its time goes (e.g.
perception while the vehicle descends to land decides nothing any more).

Run: .venv/bin/python benchmarks/bench_profile.py [--mission missions/mars_science.yaml]
     [--seeds 0 1] [--report] [--by-phase] [--json]
(benchmarks/bench_compare.py runs it against an older checkout in the same run.)
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from collections import defaultdict
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
from _seeds import add_seed_arguments, chosen_seeds

ROOT = Path(__file__).resolve().parents[1]

PARTS = ("world", "render", "map update", "detection", "LSM", "tree", "driver", "SITL")


def _targets() -> list[tuple[str, object, str]]:
    """(part, owner, attribute) of every timed entry point."""
    from autonomy.runner import run as run_module
    from autonomy.vehicle.driver import MavlinkVehicle
    from lsd.elevation.detector import ElevationDetector
    from lsm import LandingSiteManager
    from sitl.copter.simulator import Sitl
    from sitl.sensors.camera import DepthCamera

    return [
        ("world", run_module, "build_terrain"),
        ("render", DepthCamera, "render"),
        ("map update", ElevationDetector, "integrate"),
        ("detection", ElevationDetector, "detect"),
        ("LSM", LandingSiteManager, "submit"),
        ("LSM", LandingSiteManager, "process_pending"),
        ("LSM", LandingSiteManager, "set_drone_position"),
        ("driver", MavlinkVehicle, "poll"),
        ("SITL", Sitl, "step"),
    ]


PHASE_PARTS = ("render", "map update", "detection")
"""The parts ``--by-phase`` splits out of a phase's ticks (the rest is "rest of tick")."""


def _mission_phase() -> str:
    """The phase the mission tree reports now (the runner's blackboard key)."""
    import py_trees

    from behaviors import blackboard as bb

    return str(py_trees.blackboard.Blackboard.storage.get(bb.PHASE, "preflight"))


@contextmanager
def timed_parts(by_phase: dict | None = None) -> Iterator[dict[str, float]]:
    """Wrap every entry point of :func:`_targets`; yields the CPU seconds per part
    (accumulating), restores the originals on exit. Nested calls of timed parts count
    only in the outermost. ``by_phase``: also accumulate, keyed (phase, part), the CPU of
    each flight tick ("tick") and of the :data:`PHASE_PARTS` inside it, and the ticks
    ("ticks") per phase."""
    from autonomy.runner.flight import Flight

    cpu: dict[str, float] = defaultdict(float)
    depth = [0]
    saved = []

    def wrap(part: str, fn: Callable) -> Callable:
        def timed(*args, **kwargs):
            if depth[0]:
                return fn(*args, **kwargs)
            depth[0] += 1
            start = time.thread_time()
            try:
                return fn(*args, **kwargs)
            finally:
                spent = time.thread_time() - start
                cpu[part] += spent
                depth[0] -= 1
                if by_phase is not None and part in PHASE_PARTS:
                    by_phase[_mission_phase(), part] += spent

        return timed

    if by_phase is not None:
        tick = Flight.__dict__["tick"]

        def tick_timed(flight):
            # The phase the tick starts in owns it (the tree may move on inside it).
            phase = _mission_phase()
            start = time.thread_time()
            try:
                return tick(flight)
            finally:
                by_phase[phase, "tick"] += time.thread_time() - start
                by_phase[phase, "ticks"] += 1

        saved.append((Flight, "tick", tick))
        Flight.tick = tick_timed

    from autonomy.runner.flight import Flight

    attach = Flight.__dict__["attach_tree"]

    def attach_timed(flight, tree):
        # Whatever class the mission tree is, time the tick of the one flown.
        tree.tick = wrap("tree", tree.tick)
        return attach(flight, tree)

    saved.append((Flight, "attach_tree", attach))
    Flight.attach_tree = attach_timed
    for part, owner, name in _targets():
        original = owner.__dict__[name] if isinstance(owner, type) else getattr(owner, name)
        saved.append((owner, name, original))
        setattr(owner, name, wrap(part, original))
    try:
        yield cpu
    finally:
        for owner, name, original in reversed(saved):
            setattr(owner, name, original)


def profile_flight(mission, seed: int, report: bool = False, by_phase: dict | None = None
                   ) -> tuple[dict[str, float], float, float, float, str]:
    """Fly one seed with every part timed: (CPU s per part incl. "other", total CPU s,
    wall s, simulated s, outcome). ``report``: write the run's report directory as a
    campaign run does (its writing falls in "other"). ``by_phase``: accumulate the
    per-phase figures of :func:`timed_parts` into it."""
    from autonomy.campaign.worker import fly_with_page
    from autonomy.runner import fly

    with timed_parts(by_phase) as cpu, tempfile.TemporaryDirectory() as out:
        w0, c0 = time.perf_counter(), time.thread_time()
        result = fly_with_page(mission, seed, out) if report else fly(mission, seed=seed)
        total = time.thread_time() - c0
        wall = time.perf_counter() - w0
    parts = {part: cpu.get(part, 0.0) for part in PARTS}
    parts["other"] = total - sum(parts.values())
    return parts, total, wall, float(result.summary["mission_time"]), result.outcome


def main(argv: list[str] | None = None) -> int:
    from autonomy.config import load_mission

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", action="append", default=None,
                        help="mission file (repeatable; default mars_science and demo)")
    add_seed_arguments(parser)
    parser.add_argument("--report", action="store_true",
                        help="write each run's report directory (logs, tlog, btlog, "
                        "report.html) as a campaign run does")
    parser.add_argument("--by-phase", action="store_true",
                        help="also print each mission phase's simulated time and the CPU "
                        "of its ticks (render, map update, detection, the rest)")
    parser.add_argument("--json", action="store_true",
                        help="one JSON line per mission instead of the table")
    args = parser.parse_args(argv)
    args.seeds = chosen_seeds(args)
    missions = args.mission or [str(ROOT / "missions" / "mars_science.yaml"),
                                str(ROOT / "missions" / "demo.yaml")]
    if not args.json:
        print(f"machine: {os.cpu_count()} cores, load average "
              f"{' '.join(f'{v:.2f}' for v in os.getloadavg())}")
    for path in missions:
        mission = load_mission(path)
        sums: dict[str, float] = defaultdict(float)
        sim = cpu = wall = 0.0
        outcomes = []
        phases: dict[tuple[str, str], float] | None = defaultdict(float) if args.by_phase else None
        for seed in args.seeds:
            parts, total, w, s, outcome = profile_flight(mission, seed, args.report, phases)
            for part, value in parts.items():
                sums[part] += value
            sim, cpu, wall = sim + s, cpu + total, wall + w
            outcomes.append(f"{seed}:{outcome}")
        if args.json:
            line = {"mission": Path(path).name, "seeds": args.seeds, "sim": sim,
                    "cpu": cpu, "wall": wall, "parts": sums, "outcomes": outcomes}
            if phases is not None:
                line["phases"] = {f"{phase}/{part}": value
                                  for (phase, part), value in phases.items()}
            print(json.dumps(line))
            continue
        print(f"== {Path(path).name}: seeds {' '.join(map(str, args.seeds))}, "
              f"{sim:.0f} simulated s, {cpu:.2f} s CPU, {wall:.2f} s wall "
              f"({', '.join(outcomes)})")
        print(f"  {'part':<12} {'ms CPU per sim s':>17} {'share':>7}")
        for part in (*PARTS, "other"):
            print(f"  {part:<12} {sums[part] / sim * 1e3:>17.2f} {sums[part] / cpu:>7.1%}")
        print(f"  {'total':<12} {cpu / sim * 1e3:>17.2f}")
        print(f"  {sim / cpu:.1f}x real time per core (CPU), {sim / wall:.1f}x in wall time")
        if phases is not None:
            print_phases(phases, mission.tick_rate, cpu)
    return 0


def print_phases(phases: dict[tuple[str, str], float], tick_rate: float, cpu: float) -> None:
    """The ``--by-phase`` table: per phase (in the order the tree reports them) its
    simulated seconds, then CPU seconds of its ticks by part and its share of all CPU."""
    from behaviors import blackboard as bb

    seen = {phase for phase, _ in phases}
    order = [p for p in bb.PHASES if p in seen] + sorted(seen - set(bb.PHASES))
    cols = (*PHASE_PARTS, "rest of tick")
    print(f"  {'phase':<17} {'sim s':>7} " + " ".join(f"{c:>12}" for c in cols)
          + f" {'tick CPU s':>11} {'share':>6} {'x real time':>12}")
    for phase in order:
        ticks, tick = phases[phase, "ticks"], phases[phase, "tick"]
        if not ticks:
            continue
        inside = [phases[phase, part] for part in PHASE_PARTS]
        values = (*inside, tick - sum(inside))
        sim_s = ticks / tick_rate
        print(f"  {phase:<17} {sim_s:>7.0f} " + " ".join(f"{v:>12.2f}" for v in values)
              + f" {tick:>11.2f} {tick / cpu:>6.1%} {sim_s / tick if tick else 0:>11.1f}x")


if __name__ == "__main__":
    sys.exit(main())
