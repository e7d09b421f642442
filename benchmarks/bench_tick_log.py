"""Cost of the tick log (tree.btlog) and the blackboard log (blackboard.jsonl) per tick.

The landing tree flies the behaviour tests' mission (a site that fails verification, then
one that verifies) against their fake vehicle, once bare and once with
:class:`behaviors.recording.TreeRecorder` attached; only this thread's CPU time of the
flight loop is counted, the best of three runs each. Prints ms per tick for both, their
ratio, and the size of the .btlog.

Run: .venv/bin/python benchmarks/bench_tick_log.py
"""

from __future__ import annotations

import os
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import _checkout  # noqa: E402, F401  (this checkout's packages first)
from bench_tree import _load_fakes  # noqa: E402

from autonomy.clock import SimClock  # noqa: E402
from behaviors.recording import TICK_LOG, TreeRecorder  # noqa: E402
from behaviors.settings import MissionPlan  # noqa: E402
from behaviors.tree import build_mission_tree  # noqa: E402
from lsm import LandingSiteManager, LsmSettings  # noqa: E402


def flight(record: bool) -> tuple[float, int, int]:
    """(CPU seconds, ticks, .btlog bytes) of one flight."""
    fakes = _load_fakes()
    plan = MissionPlan(waypoints=[(0, 0, 100), (150, 0, 100)])
    clock = SimClock()
    vehicle = fakes.FakeVehicle(clock)
    lsm = LandingSiteManager(LsmSettings(max_distance=150.0))
    tree = build_mission_tree(plan, vehicle, lsm, clock, np.random.default_rng(0))
    sites = [fakes.ScriptedSite(120.0, 10.0, fails_verification=True),
             fakes.ScriptedSite(80.0, -20.0)]
    with tempfile.TemporaryDirectory() as out:
        recorder = TreeRecorder(tree, out, clock.now) if record else None
        start = time.thread_time()
        done = fakes.fly(tree, vehicle, clock, lsm, fakes.ScriptedDetector(sites))
        cpu = time.thread_time() - start
        size = 0
        if recorder is not None:
            recorder.close()
            size = os.path.getsize(os.path.join(out, TICK_LOG))
    return cpu, done.ticks, size


def main() -> None:
    bare = min(flight(False) for _ in range(3))
    logged = min(flight(True) for _ in range(3))
    ticks = bare[1]
    print(f"== tick log: the landing tree against the fake vehicle, {ticks} ticks ==")
    print(f"  without the logs: {bare[0] / ticks * 1e3:.3f} ms CPU per tick")
    print(f"  with tree.btlog + blackboard.jsonl: {logged[0] / ticks * 1e3:.3f} ms CPU per tick "
          f"({logged[0] / bare[0]:.2f}x); tree.btlog {logged[2]:,} bytes")


if __name__ == "__main__":
    main()
