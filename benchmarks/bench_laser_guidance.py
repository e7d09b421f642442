"""The guiding direction estimator (seed 004, Algorithm 1) against the paper's tables 1 and 3
and figure 3, and the laser guidance flown end to end against landing in place.

Run: .venv/bin/python benchmarks/bench_laser_guidance.py [--flights N] [--mars N]

Figures:
- table 1: RMSE (deg) of the estimate against a constant bearing, for 100, 500, 2,000 and
  10,000 particles, over 200 updates after 20 to settle, 20 seeds; with exact readings (the
  paper's simulation) and with ring-sensor readings (30 deg sectors, 5 % reflections);
- table 3: time per update (ms, median of 200 on this machine; paper: 27.2 / 91.7 / 397.1 /
  1642.4 ms on an ODROID XU4) and the RMSE of the first estimate after initialisation;
- figure 3: the light's bearing jumps by 180 deg: readings until the estimate is within
  10 deg again and stays there for 20, with and without dispersion (median of 20 seeds);
- paired flights: the demo mission with GPS lost at a random time (20-60 s after boot) and a
  laser at a random point 40-100 m from home at night, flown with the laser guidance and
  with it turned off: touchdown distance to the laser, safe touchdowns, outcomes; and the
  same on the Mars science mission (GPS lost 50-150 s after boot, the laser on a point of
  the ground truth's safe ground 50-150 m from home), where landing in place is often unsafe.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
import numpy as np
import yaml

from guidance import DirectionEstimatorSettings, GuidingDirectionEstimator
from guidance.detector import ring_bearing
from guidance.direction import wrap_angle

COUNTS = (100, 500, 2000, 10_000)
PAPER_TABLE_1 = {100: 2.712, 500: 0.609, 2000: 0.204, 10_000: 0.129}
PAPER_TABLE_3_MS = {100: 27.2, 500: 91.7, 2000: 397.1, 10_000: 1642.4}
PAPER_TABLE_3_RMSE = {100: 0.0568, 500: 0.0239, 2000: 0.0118, 10_000: 0.0047}
DEMO = Path(__file__).resolve().parents[1] / "missions" / "demo.yaml"


def ring_reading(bearing: float, rng: np.random.Generator) -> float:
    """What the ring reports for light from ``bearing``: the middle of its sector, or of the
    arc spanning a reflection too (5 % of the readings)."""
    sector = 2 * math.pi / 12
    mask = 1 << int(round((bearing % (2 * math.pi)) / sector)) % 12
    if rng.random() < 0.05:
        mask |= 1 << int(rng.integers(12))
    return ring_bearing(mask)


def rmse_constant(n: int, seed: int, ring: bool) -> float:
    rng = np.random.default_rng(1000 + seed)
    truth = float(rng.uniform(-math.pi, math.pi))
    estimator = GuidingDirectionEstimator(
        DirectionEstimatorSettings(n_particles=n), np.random.default_rng(seed)
    )
    errors = []
    for k in range(220):
        z = ring_reading(truth, rng) if ring else truth
        estimate = estimator.update(z)
        if k >= 20:
            errors.append(float(wrap_angle(estimate - truth)))
    return math.sqrt(float(np.mean(np.square(errors))))


def table_1() -> None:
    print("Table 1: RMSE (deg) against a constant bearing, 20 seeds x 200 updates")
    print(f"{'particles':>10} {'paper':>8} {'exact':>8} {'ring':>8}")
    for n in COUNTS:
        exact = statistics.mean(rmse_constant(n, s, False) for s in range(20))
        ring = statistics.mean(rmse_constant(n, s, True) for s in range(20))
        print(f"{n:>10} {PAPER_TABLE_1[n]:>8.3f} {math.degrees(exact):>8.3f} "
              f"{math.degrees(ring):>8.3f}")


def table_3() -> None:
    print("\nTable 3: time per update (ms) and RMSE (rad) of the first estimate")
    print(f"{'particles':>10} {'paper ms':>9} {'here ms':>8} {'paper rad':>10} {'here rad':>9}")
    for n in COUNTS:
        estimator = GuidingDirectionEstimator(
            DirectionEstimatorSettings(n_particles=n), np.random.default_rng(1)
        )
        rng = np.random.default_rng(2)
        times = []
        for _ in range(200):
            z = float(rng.normal(0.5, 0.1))
            t0 = time.perf_counter()
            estimator.update(z)
            times.append(time.perf_counter() - t0)
        first = []
        for seed in range(200):
            truth = float(np.random.default_rng(seed).uniform(-math.pi, math.pi))
            fresh = GuidingDirectionEstimator(
                DirectionEstimatorSettings(n_particles=n), np.random.default_rng(seed)
            )
            first.append(float(wrap_angle(fresh.update(truth) - truth)))
        rmse = math.sqrt(float(np.mean(np.square(first))))
        print(f"{n:>10} {PAPER_TABLE_3_MS[n]:>9.1f} {1e3 * statistics.median(times):>8.3f} "
              f"{PAPER_TABLE_3_RMSE[n]:>10.4f} {rmse:>9.4f}")


def settle_after_jump(dispersion: float, seed: int) -> int:
    rng = np.random.default_rng(500 + seed)
    estimator = GuidingDirectionEstimator(
        DirectionEstimatorSettings(dispersion_fraction=dispersion), np.random.default_rng(seed)
    )
    before, after = math.radians(30.0), math.radians(210.0)
    for _ in range(100):
        estimator.update(ring_reading(before, rng))
    errors = [
        abs(math.degrees(wrap_angle(estimator.update(ring_reading(after, rng)) - after)))
        for _ in range(500)
    ]
    for k in range(len(errors)):
        if all(e < 10.0 for e in errors[k : k + 20]):
            return k + 1
    return len(errors)


def figure_3() -> None:
    print("\nFigure 3: readings to settle within 10 deg after a 180 deg jump (median, 20 seeds;"
          " 500 = not within 500)")
    for dispersion in (0.10, 0.0):
        steps = [settle_after_jump(dispersion, s) for s in range(20)]
        print(f"  dispersion {dispersion:.2f}: {statistics.median(steps):.0f} readings "
              f"(min {min(steps)}, max {max(steps)})")


def flights(count: int) -> None:
    from autonomy.runner import fly

    print(f"\nPaired flights: demo mission, GPS lost at random, laser at night, {count} pairs")
    rng = np.random.default_rng(2024)
    rows = {True: [], False: []}
    for i in range(count):
        at = float(rng.uniform(20.0, 60.0))
        angle, radius = float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(40.0, 100.0))
        emitter = (radius * math.cos(angle), radius * math.sin(angle))
        for guided in (True, False):
            data = yaml.safe_load(DEMO.read_text())
            data["seed"] = i
            data["world"]["size"] = [300.0, 300.0]
            data["sitl"]["gps_loss"] = {"at": at}
            data["sitl"]["laser"] = {"emitter": list(emitter), "condition": "night"}
            data["landing"]["laser_guidance"] = {"enabled": guided}
            rows[guided].append(_flown(fly(Mission_of(data)).summary, emitter))
    _print_rows(rows)


def mars_flights(count: int) -> None:
    """The Mars science mission, GPS lost at random after take-off, a laser at night on a
    ground-truth safe point 50-150 m from home: guided vs land in place."""
    from autonomy.config import load_mission
    from autonomy.runner import fly
    from autonomy.runner.world import FlightSeeds, build_terrain
    from sitl.terrain import is_safe

    mars = DEMO.with_name("mars_science.yaml")
    print(f"\nPaired flights: Mars science mission, GPS lost at random, laser at night on safe "
          f"ground, {count} pairs")
    rng = np.random.default_rng(7)
    rows = {True: [], False: []}
    for i in range(count):
        base = load_mission(mars)
        terrain = build_terrain(base, FlightSeeds.derive(i).terrain)
        while True:  # a safe point for the laser
            angle, radius = float(rng.uniform(0, 2 * math.pi)), float(rng.uniform(50.0, 150.0))
            emitter = (radius * math.cos(angle), radius * math.sin(angle))
            if is_safe(terrain, *emitter):
                break
        at = float(rng.uniform(50.0, 150.0))
        for guided in (True, False):
            data = base.source_data()
            data["seed"] = i
            data.setdefault("sitl", {})["gps_loss"] = {"at": at}
            data["sitl"]["laser"] = {"emitter": list(emitter), "condition": "night"}
            data.setdefault("landing", {})["laser_guidance"] = {"enabled": guided}
            rows[guided].append(_flown(fly(Mission_of(data)).summary, emitter))
    _print_rows(rows)


def Mission_of(data):  # noqa: N802 - reads like the model it builds
    from autonomy.config import Mission

    return Mission.model_validate(data)


def _flown(summary: dict, emitter: tuple[float, float]) -> tuple:
    td = summary.get("touchdown") or {}
    distance = math.hypot(td.get("x", math.nan) - emitter[0], td.get("y", math.nan) - emitter[1])
    return summary["outcome"], summary.get("touchdown_safe"), distance


def _print_rows(rows: dict) -> None:
    for guided, label in ((True, "laser guidance"), (False, "land in place")):
        r = rows[guided]
        distances = [d for _, _, d in r if math.isfinite(d)]
        outcomes: dict[str, int] = {}
        for outcome, _, _ in r:
            outcomes[outcome] = outcomes.get(outcome, 0) + 1
        safe = sum(1 for _, s, _ in r if s is True)
        print(f"  {label:>15}: median distance to the laser {statistics.median(distances):6.2f} m"
              f" (max {max(distances):6.2f}), safe {safe}/{len(r)}, outcomes {outcomes}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--flights", type=int, default=10, help="paired demo flights")
    parser.add_argument("--mars", type=int, default=5, help="paired Mars flights")
    args = parser.parse_args()
    table_1()
    table_3()
    figure_3()
    if args.flights > 0:
        flights(args.flights)
    if args.mars > 0:
        mars_flights(args.mars)


if __name__ == "__main__":
    main()
