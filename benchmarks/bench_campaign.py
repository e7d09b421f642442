"""Campaign throughput: simulated flight-hours per wall-clock hour per core.

Flies ``--runs`` seeded lockstep flights of a mission (default missions/demo.yaml) through
the campaign machinery (local process pool of ``--workers`` processes, or ``--scheduler``)
into a fresh output directory, and compares with flying the same seeds one after another in
this process. The campaign figure includes everything a user waits for: starting workers,
shipping missions, appending runs.jsonl, the summary and the plot.

    flight-hours per wall-hour per core = (sum of simulated mission times / wall time) / cores

It also prints the fixed cost every run pays before it flies (world generation and the
depth camera's height bounds, both from the run's seed), what a fresh process pays to import
the flight stack, what a pool worker pays from its fork to the end of a one-tick flight with
and without the fork server's preloading, and the wall time of ``--extrapolate`` runs
(default 200) at the measured rate.

Run: .venv/bin/python benchmarks/bench_campaign.py [--runs 8] [--workers K]
     [--mission missions/demo.yaml] [--scheduler tcp://HOST:PORT | local] [--extrapolate 200]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--probe-worker"]:  # a fresh process measuring one pool worker
        _probe_worker(*argv[1:3])
        return 0
    from autonomy.campaign import run_campaign, run_seed
    from autonomy.campaign.backends import default_workers
    from autonomy.config import load_mission
    from autonomy.runner import fly

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", default=str(ROOT / "missions" / "demo.yaml"))
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--scheduler", default=None)
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--serial-runs", type=int, default=2,
                        help="flights for the in-process baseline")
    parser.add_argument("--extrapolate", type=int, default=200,
                        help="print the wall time of this many runs at the measured rate")
    args = parser.parse_args(argv)

    mission = load_mission(args.mission)
    workers = args.workers or default_workers()
    print(f"campaign throughput: {Path(args.mission).name}, {args.runs} runs, "
          f"{'scheduler ' + args.scheduler if args.scheduler else f'{workers} workers'} "
          f"(machine: {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f})")

    # Baseline: the same seeds flown one after another in this process (no pool at all).
    sim = wall = 0.0
    for i in range(min(args.serial_runs, args.runs)):
        start = time.perf_counter()
        result = fly(mission, seed=run_seed(args.seed, i))
        wall += time.perf_counter() - start
        sim += result.summary["mission_time"]
    if wall:
        print(f"  in-process flights: {min(args.serial_runs, args.runs)} in {wall:.1f} s wall, "
              f"{sim:.0f} sim s -> {sim / wall:.1f} flight-h per wall-h (1 core)")

    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        result = run_campaign(mission, runs=args.runs, out_dir=out, seed=args.seed,
                              workers=args.workers, scheduler=args.scheduler, quiet=True)
        wall = time.perf_counter() - start
    flown = [r for r in result.records if r["outcome"] != "error"]
    _fixed_cost(mission, args.mission, args.seed)
    sim = sum(r["mission_time"] or 0.0 for r in flown)
    per_run = sorted(r["wall_time"] for r in flown if r.get("wall_time"))
    median = per_run[len(per_run) // 2] if per_run else float("nan")
    cores = workers if not args.scheduler else max(1, len({r["worker"] for r in result.records}))
    rate = sim / wall
    print(f"  campaign: {len(result.records)} runs ({len(result.records) - len(flown)} errors) "
          f"in {wall:.1f} s wall, {sim:.0f} sim s, median flight {median:.2f} s wall")
    print(f"  throughput: {rate:.1f} flight-h per wall-h, {rate / cores:.1f} per core "
          f"({cores} {'workers' if not args.scheduler else 'worker processes seen'})")
    if args.extrapolate:
        per_run = wall / len(result.records)
        print(f"  {args.extrapolate} runs at this rate (extrapolated from {len(result.records)}): "
              f"{args.extrapolate * per_run / 60:.1f} min wall on {cores} workers")
    return 0


def _fixed_cost(mission, mission_path: str, seed: int) -> None:
    """What every run pays before it flies: the world (generated from the run's seed, so
    it cannot be shared between runs), the depth camera's height bounds of it (built on
    the first frame), and the rest of a flight's setup (a flight of one tick)."""
    from autonomy.campaign import run_seed
    from autonomy.runner import fly
    from autonomy.runner.world import FlightSeeds, build_terrain

    seeds = FlightSeeds.derive(run_seed(seed, 0))
    start = time.thread_time()
    terrain = build_terrain(mission, seeds.terrain)
    world = time.thread_time() - start
    bounds = 0.0
    if mission.perception.detector in ("elevation_map", "depth_costmap"):
        from sitl.sensors.raycast import HeightBounds

        start = time.thread_time()
        HeightBounds(terrain)
        bounds = time.thread_time() - start
    start = time.thread_time()
    fly(mission.model_copy(update={"time_limit": 1.0 / mission.tick_rate}), seed=0)
    setup = time.thread_time() - start
    print(f"  fixed cost per run (CPU): world {world:.2f} s, height bounds {bounds:.2f} s, "
          f"a one-tick flight with its world {setup:.2f} s")
    start_cpu, start_wall = _process_start()
    print(f"  fixed cost per fresh process (`lander fly`, a Dask worker): importing the flight "
          f"stack {start_cpu:.2f} s CPU ({start_wall:.2f} s wall)")
    cold, warm = (_worker_start(mission_path, preload) for preload in ("worker", "stack"))
    print(f"  a local pool worker's CPU from its fork to the end of a one-tick flight: "
          f"{cold:.2f} s forked from a server that imported only the worker module, "
          f"{warm:.2f} s from one that imported the flight stack and loaded its compiled "
          f"kernels (as the pool does; the server pays that once per campaign)")


def _worker_start(mission_path: str, preload: str) -> float:
    """CPU seconds a fork-server worker spends from its fork to the end of a one-tick
    flight of the mission, its server having preloaded ``preload`` ("worker": the worker
    module only; "stack": what the local pool preloads for lander flights); the best of
    three fresh servers."""
    import subprocess

    best = float("inf")
    for _ in range(3):
        out = subprocess.run([sys.executable, __file__, "--probe-worker", preload, mission_path],
                             check=True, cwd=ROOT, capture_output=True, text=True).stdout
        best = min(best, float(out.split()[-1]))
    return best


def _probe_worker(preload: str, mission_path: str) -> None:
    """Start a fork server with ``preload``, fly one tick in a worker, print its CPU."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from autonomy.config import load_mission

    modules = ["__main__", "autonomy.campaign.worker"]
    if preload == "stack":
        from autonomy.campaign.warm import preload_modules

        modules += preload_modules([load_mission(mission_path)])
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(modules)
    with ProcessPoolExecutor(1, mp_context=context) as pool:
        print(pool.submit(_one_tick_cpu, mission_path).result())


def _one_tick_cpu(mission_path: str) -> float:
    """This process's CPU seconds so far after a one-tick flight of the mission (a worker
    flies as :func:`autonomy.campaign.worker.fly_with_page` does)."""
    import resource

    from autonomy.campaign.worker import fly_with_page
    from autonomy.config import load_mission

    mission = load_mission(mission_path)
    fly_with_page(mission.model_copy(update={"time_limit": 1.0 / mission.tick_rate}), seed=0)
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def _process_start() -> tuple[float, float]:
    """CPU and wall seconds of a fresh interpreter importing what a flight needs (the best
    of three, as a worker or `lander fly` starts)."""
    import resource
    import subprocess

    best = (float("inf"), float("inf"))
    for _ in range(3):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        start = time.perf_counter()
        subprocess.run([sys.executable, "-c", "import autonomy.runner, autonomy.campaign"],
                       check=True, cwd=ROOT)
        wall = time.perf_counter() - start
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        best = min(best, (cpu, wall))
    return best


if __name__ == "__main__":
    sys.exit(main())
