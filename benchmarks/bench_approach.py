"""The approach to the site: the thesis's climb-traverse-descent against the minimum-snap
trajectory over the elevation map (landing.approach.method), on the same missions and seeds.

Prints, per method, the outcomes and the means of time to land, distance flown and battery
used, and the CPU time the planner took per plan (the site's whole plan: clearance, path search
and trajectory) with, separately, the part spent generating minimum-snap trajectories.

    .venv/bin/python benchmarks/bench_approach.py                      # mars_demo, 5 seeds
    .venv/bin/python benchmarks/bench_approach.py --seeds 20 --mission missions/mars_science.yaml
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from autonomy.config import apply_overrides, load_mission  # noqa: E402
from autonomy.perception import approach as approach_module  # noqa: E402
from autonomy.runner import fly  # noqa: E402
from planning import approach as planning_approach  # noqa: E402


def _timed_planner():
    """Wrap MapApproachPlanner.plan and the trajectory generation inside it to collect their
    CPU time per plan: (plan times, trajectory times), seconds."""
    times: list[float] = []
    generating: list[float] = []
    original = approach_module.MapApproachPlanner.plan
    generate = planning_approach.min_snap_trajectory

    def plan(self, start, goal):
        generating.append(0.0)
        t0 = time.process_time()
        try:
            return original(self, start, goal)
        finally:
            times.append(time.process_time() - t0)

    def min_snap_trajectory(*args, **kwargs):
        t0 = time.process_time()
        try:
            return generate(*args, **kwargs)
        finally:
            generating[-1] += time.process_time() - t0

    approach_module.MapApproachPlanner.plan = plan
    planning_approach.min_snap_trajectory = min_snap_trajectory
    return times, generating


def _percentiles(seconds: list[float]) -> str:
    ms = np.array(seconds) * 1000.0
    return (f"median {np.median(ms):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms, "
            f"slowest {ms.max():.2f} ms CPU")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", default=str(ROOT / "missions" / "mars_demo.yaml"))
    parser.add_argument("--seeds", type=int, default=5)
    args = parser.parse_args()
    base = load_mission(args.mission)
    plan_times, trajectory_times = _timed_planner()
    print(f"approach benchmark: {Path(args.mission).name}, seeds {base.seed}.."
          f"{base.seed + args.seeds - 1}")
    print(f"{'method':<16}{'outcomes':<34}{'time to land s':>15}{'distance m':>12}"
          f"{'battery %':>11}{'wall s':>8}")
    for method in ("clear_altitude", "trajectory"):
        mission = apply_overrides(base, {"landing.approach.method": method})
        outcomes, land, dist, battery = Counter(), [], [], []
        wall = time.perf_counter()
        for seed in range(base.seed, base.seed + args.seeds):
            s = fly(mission, seed=seed).summary
            outcomes[s["outcome"]] += 1
            if s.get("time_to_land") is not None:
                land.append(s["time_to_land"])
            dist.append(s["distance"])
            battery.append(s["energy"]["battery_used"])
        wall = time.perf_counter() - wall
        text = ", ".join(f"{k} {v}" for k, v in sorted(outcomes.items()))
        mean_land = statistics.fmean(land) if land else float("nan")
        print(f"{method:<16}{text:<34}{mean_land:>15.1f}{statistics.fmean(dist):>12.0f}"
              f"{statistics.fmean(battery):>11.1f}{wall:>8.0f}")
    if plan_times:
        print(f"planner, whole plan per site: {len(plan_times)} plans, "
              f"{_percentiles(plan_times)}")
        made = [t for t in trajectory_times if t > 0]
        if made:
            print(f"  of which trajectory generation: {len(made)} plans, {_percentiles(made)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
