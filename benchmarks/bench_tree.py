"""Speed of the mission behaviour tree.

Section 1 (tick cost): the full mission tree flies whole missions in lockstep against the
kinematic fake vehicle of the behaviour tests and the real Landing Site Manager; only
``tree.tick()`` is timed, once per tick, over every phase (preflight to touchdown), both in
wall time (perf_counter: includes preemption by other processes on a busy machine) and in
this thread's CPU time (thread_time). Target: median < 0.5 ms. Further sections (e.g. the
end-to-end lockstep speed) are added to SECTIONS below.

Run: .venv/bin/python benchmarks/bench_tree.py
"""

from __future__ import annotations

import importlib.util
import statistics
import sys
import time
from collections import defaultdict
from collections.abc import Callable
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
import numpy as np
import py_trees

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.settings import MissionPlan
from behaviors.tree import build_mission_tree
from lsm import LandingSiteManager, LsmSettings

ROOT = Path(__file__).resolve().parents[1]
TICK_TARGET_MS = 0.5


def _load_fakes():
    """The behaviour tests' fake vehicle and scripted detector (tests/behaviors/fakes.py)."""
    name = "behaviors_fakes"
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, ROOT / "tests/behaviors/fakes.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


def _percentile_ms(samples: list[float], q: float) -> float:
    return float(np.percentile(samples, q)) * 1e3


Timings = tuple[list[float], list[float], dict[str, list[float]]]


def _fly_timed(n_sites: int, fails: int, seed: int) -> Timings:
    """Fly one mission; return the wall and CPU time of every tick, and the CPU times
    grouped by the phase the tick started in."""
    fakes = _load_fakes()
    rng = np.random.default_rng(seed)
    plan = MissionPlan(waypoints=[(0, 0, 100), (150, 0, 100), (150, 80, 100), (0, 80, 100)])
    clock = SimClock()
    vehicle = fakes.FakeVehicle(clock)
    lsm = LandingSiteManager(LsmSettings(max_distance=200.0))
    xy = rng.uniform((-20, -20), (170, 100), size=(n_sites, 2))
    sites = [
        fakes.ScriptedSite(float(x), float(y), roughness=float(r))
        for (x, y), r in zip(xy, rng.uniform(0.1, 1, n_sites), strict=True)
    ]
    # The best sites (flat, large, near the last waypoint) are false positives: the tree
    # verifies, bans and retries before it lands.
    sites += [
        fakes.ScriptedSite(10.0 * i, 70.0, roughness=0.0, size=10.0, fails_verification=True)
        for i in range(fails)
    ]
    detector = fakes.ScriptedDetector(sites, footprint=0.5)
    tree = build_mission_tree(plan, vehicle, lsm, clock, np.random.default_rng(seed))
    board = py_trees.blackboard.Client(name="bench")
    board.register_key(key=keys.PHASE, access=py_trees.common.Access.READ)

    wall: list[float] = []
    cpu: list[float] = []
    by_phase: dict[str, list[float]] = defaultdict(list)
    dt, tick = 0.05, 0
    while clock.now() < 3000.0:
        clock.advance(dt)
        vehicle.step(dt)
        lsm.set_drone_position(vehicle.position)
        if tick % 4 == 0:  # 5 Hz perception at a 20 Hz tick
            for observation in detector.observe(vehicle.position, clock.now()):
                lsm.submit(observation)
            lsm.process_pending()
        phase = board.get(keys.PHASE)
        t0, c0 = time.perf_counter(), time.thread_time()
        tree.tick()
        c1, t1 = time.thread_time(), time.perf_counter()
        wall.append(t1 - t0)
        cpu.append(c1 - c0)
        by_phase[phase].append(c1 - c0)
        tick += 1
        if tree.root.status != py_trees.common.Status.RUNNING:
            break
    if tree.root.status != py_trees.common.Status.SUCCESS or board.get(keys.PHASE) != "done":
        raise RuntimeError(f"benchmark mission did not land: {tree.root.status}")
    return wall, cpu, by_phase


def section_tick_cost() -> None:
    print("== 1. one tick of the full mission tree (fake vehicle, real LSM) ==")
    for n_sites, fails in ((5, 0), (100, 2)):
        wall: list[float] = []
        cpu: list[float] = []
        by_phase: dict[str, list[float]] = defaultdict(list)
        for seed in range(5):
            w, c, p = _fly_timed(n_sites, fails, seed)
            wall += w
            cpu += c
            for phase, samples in p.items():
                by_phase[phase] += samples
        median = statistics.median(cpu) * 1e3
        verdict = "met" if median < TICK_TARGET_MS else "MISSED"
        print(
            f"{n_sites} sites, {fails} false positives: {len(cpu)} ticks over 5 missions\n"
            f"  cpu  median {median:.3f} ms, p99 {_percentile_ms(cpu, 99):.3f} ms, "
            f"max {max(cpu) * 1e3:.3f} ms (target median < {TICK_TARGET_MS} ms: {verdict})\n"
            f"  wall median {statistics.median(wall) * 1e3:.3f} ms, "
            f"p99 {_percentile_ms(wall, 99):.3f} ms, max {max(wall) * 1e3:.3f} ms"
        )
        print("  cpu per phase:")
        for phase in keys.PHASES:
            samples = by_phase.get(phase)
            if samples:
                print(
                    f"    {phase:<17} {len(samples):>6} ticks  median "
                    f"{statistics.median(samples) * 1e3:.3f} ms  p99 "
                    f"{_percentile_ms(samples, 99):.3f} ms"
                )


def section_end_to_end() -> None:
    """Section 2 (runner): whole missions flown end to end in lockstep by
    :func:`autonomy.runner.fly` - world generation, embedded SITL, MAVLink driver, tree, LSM
    and perception - with no report files written. Prints how many times faster than real
    time they run (simulated mission time / wall time, and / this process's CPU time)."""
    from autonomy.config import load_mission
    from autonomy.runner import fly

    print("== 2. end-to-end lockstep flights (world + SITL + driver + tree + LSM + perception) ==")
    for name, runs in (("demo.yaml", 3), ("mars_science.yaml", 2)):
        mission = load_mission(ROOT / "missions" / name)
        sim, wall, cpu, outcomes = [], [], [], []
        for seed in range(runs):
            w0, c0 = time.perf_counter(), time.process_time()
            result = fly(mission, seed=seed)
            wall.append(time.perf_counter() - w0)
            cpu.append(time.process_time() - c0)
            sim.append(result.summary["mission_time"])
            outcomes.append(result.outcome)
        factors = [s / w for s, w in zip(sim, wall, strict=True)]
        cpu_factors = [s / c for s, c in zip(sim, cpu, strict=True)]
        print(
            f"{name}: {runs} seeds, simulated {statistics.median(sim):.0f} s per flight "
            f"(median), wall {statistics.median(wall):.2f} s, CPU {statistics.median(cpu):.2f} s\n"
            f"  {statistics.median(factors):.0f}x faster than real time (wall, median; min "
            f"{min(factors):.0f}x), {statistics.median(cpu_factors):.0f}x per CPU second; "
            f"outcomes: {', '.join(outcomes)}"
        )


SECTIONS: list[Callable[[], None]] = [section_tick_cost, section_end_to_end]


def main() -> int:
    for section in SECTIONS:
        section()
    return 0


if __name__ == "__main__":
    sys.exit(main())
