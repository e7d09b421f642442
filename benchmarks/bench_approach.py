"""The approach to the site and the descent watch, in paired campaigns (the same seeds in both
arms) and by the planner's CPU time.

``--campaign approach``: the thesis's climb-traverse-descent against the minimum-snap
trajectory over the elevation map (landing.approach.method). Per arm: outcomes, the means of
time to land and battery used, the median of each flight's peak jerk on the approach, and the
smallest clearance to the ground truth while crossing to a site (vehicle z minus the true
terrain height below it, from the flight's trace, more than 2 m from where each approach began
and ended); then the paired differences over the seeds
both arms landed; then the planner's CPU time per site (the whole plan: clearance, path search
and trajectory) and, separately, the part spent generating minimum-snap trajectories.

``--campaign watch``: the descent watch off against on, over generated worlds with a tall
obstacle beside the site or a car driving across it (see ``watch_mission``): collisions and
unsafe touchdowns judged by the simulator's ground truth.

    .venv/bin/python benchmarks/bench_approach.py                       # mars_demo, 8 seeds
    .venv/bin/python benchmarks/bench_approach.py --seeds 20 --mission missions/mars_science.yaml
    .venv/bin/python benchmarks/bench_approach.py --campaign watch --seeds 8 [--spare-site]
    .venv/bin/python benchmarks/bench_approach.py --campaign generation   # trajectories alone
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
from _checkout import ROOT  # noqa: E402  (this checkout's packages first)

from autonomy.config import apply_overrides, load_mission  # noqa: E402
from autonomy.perception import approach as approach_module  # noqa: E402
from autonomy.runner import fly  # noqa: E402
from autonomy.runner.world import FlightSeeds, build_terrain  # noqa: E402
from planning import approach as planning_approach  # noqa: E402

APPROACH_PHASES = ("navigate_to_site",)


def _timed_planner():
    """Wrap MapApproachPlanner.plan and the trajectory generation inside it to collect their
    CPU time per plan: (plan times, trajectory times), seconds."""
    times: list[float] = []
    generating: list[float] = []
    original = approach_module.MapApproachPlanner.plan
    generate = planning_approach.cruise_trajectory

    def plan(self, start, goal):
        generating.append(0.0)
        t0 = time.process_time()
        try:
            return original(self, start, goal)
        finally:
            times.append(time.process_time() - t0)

    def cruise_trajectory(*args, **kwargs):
        t0 = time.process_time()
        try:
            return generate(*args, **kwargs)
        finally:
            generating[-1] += time.process_time() - t0

    approach_module.MapApproachPlanner.plan = plan
    planning_approach.cruise_trajectory = cruise_trajectory
    return times, generating


def _chosen_sites() -> list:
    """Wrap GetLandingSite.update to collect the record of each site chosen for a try."""
    from py_trees.common import Status

    from behaviors import landing

    chosen: list = []
    original = landing.GetLandingSite.update

    def update(self):
        status = original(self)
        if status == Status.SUCCESS:
            chosen.append(self.blackboard.get(self.site_key))
        return status

    landing.GetLandingSite.update = update
    return chosen


def _tries(chosen, events, terrain, doubtful: float) -> list[tuple[str, bool, bool]]:
    """Each verification try: (what the chosen site's record rested on, safe by the ground
    truth, passed). The record: 'first' (the first try, from the cruise), 'doubtful' (seen
    no lower than the detector's doubtful_altitude: every close look found a step near it
    that only the noise tolerance forgave), 'high' (seen from above it) or 'low' (below)."""
    from sitl.terrain import is_safe

    outcomes = [e["new"] == "SUCCESS" for e in events
                if e.get("behaviour") == "LandingSiteVerification"
                and e.get("new") in ("SUCCESS", "FAILURE")]
    out = []
    for k, (site, passed) in enumerate(zip(chosen, outcomes, strict=False)):
        altitude = site.verification_altitude
        kind = ("first" if k == 0 else "doubtful" if abs(altitude - doubtful) < 1e-6
                else "high" if altitude > doubtful else "low")
        out.append((kind, bool(is_safe(terrain, site.x, site.y)), passed))
    return out


def _in_phases(t: np.ndarray, phases: list[tuple[float, str]], wanted) -> np.ndarray:
    """(N,) bool: samples taken while one of ``wanted`` phases ran."""
    starts = np.array([s for s, _ in phases] + [np.inf])
    names = [p for _, p in phases]
    index = np.searchsorted(starts, t, side="right") - 1
    return np.array([i >= 0 and names[i] in wanted for i in index], dtype=bool)


def _transit_clearances(t, xyz, phases, terrain) -> list[float]:
    """Smallest height above the true terrain while crossing to a site, one per approach
    (navigate_to_site): its samples more than 2 m horizontally from where it began and ended
    (the climb out of a low hover and the arrival are the descent's business)."""
    mask = _in_phases(t, phases, APPROACH_PHASES)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], mask.astype(int), [0]])))
    lowest = []
    for a, b in zip(edges[::2], edges[1::2], strict=True):
        p = xyz[a:b]
        away = (np.hypot(*(p[:, :2] - p[0, :2]).T) > 2.0) & (np.hypot(*(p[:, :2] - p[-1, :2]).T)
                                                             > 2.0)
        if away.any():
            q = p[away]
            lowest.append(float(np.min(q[:, 2] - terrain.height(q[:, 0], q[:, 1]))))
    return lowest


def _attempts(t, phases, battery) -> list[tuple[bool, float, float]]:
    """Each approach and descent to a site: (from a low hover, seconds, battery % used) from
    the start of navigate_to_site to the start of the verification that follows."""
    out = []
    for k, (start, phase) in enumerate(phases):
        if phase != "navigate_to_site":
            continue
        end = next((when for when, p in phases[k + 1:] if p == "verification"), None)
        if end is None:
            continue
        i, j = np.searchsorted(t, [start, end])
        j = min(j, len(t) - 1)
        after_a_try = any(p == "verification" for _, p in phases[:k])
        out.append((after_a_try, end - start,
                    float(battery[i] - battery[j])))
    return out


def _peak_jerk(t: np.ndarray, xyz: np.ndarray, mask: np.ndarray) -> float:
    """Largest |d^3 p / dt^3| (m/s^3) by finite differences of the trace where ``mask``."""
    if mask.sum() < 5:
        return float("nan")
    dt = float(np.median(np.diff(t)))
    jerk = np.diff(xyz, n=3, axis=0) / dt**3
    inside = mask[3:] & mask[:-3]
    return float(np.linalg.norm(jerk[inside], axis=1).max()) if inside.any() else float("nan")


def fly_one(job: tuple[str, dict, int]) -> dict:
    """One flight of the campaign (a worker process): its summary figures."""
    mission_path, overrides, seed = job
    plan_times, trajectory_times = _timed_planner()
    chosen = _chosen_sites()
    mission = apply_overrides(load_mission(mission_path), overrides)
    result = fly(mission, seed=seed)
    s = result.summary
    t, xyz, battery = result.data.trace.arrays()
    phases = result.data.trace.phases
    terrain = build_terrain(mission.model_copy(update={"seed": seed}),
                            FlightSeeds.derive(seed).terrain)
    return {
        "seed": seed, "outcome": s["outcome"], "time_to_land": s.get("time_to_land"),
        "battery": s["energy"]["battery_used"], "wh": s["energy"]["wh"],
        "distance": s["distance"], "tries": s.get("verification_attempts"),
        "touchdown_safe": s.get("touchdown_safe"), "collisions": s.get("collisions") or 0,
        "peak_jerk": _peak_jerk(t, xyz, _in_phases(t, phases, APPROACH_PHASES)),
        "clearances": _transit_clearances(t, xyz, phases, terrain),
        "attempts": _attempts(t, phases, battery),
        "verified": sum(e.get("behaviour") == "LandingSiteVerification"
                        and e.get("new") == "SUCCESS" for e in result.events),
        "flown": sum(e.get("behaviour") == "FlyApproachTrajectory" and e.get("new") == "SUCCESS"
                     for e in result.events),
        "fallbacks": sum(e.get("behaviour") == "FlyApproachTrajectory"
                         and e.get("new") == "FAILURE" for e in result.events),
        "plan_times": plan_times, "trajectory_times": trajectory_times,
        "tries_by_site": _tries(chosen, result.events, terrain,
                                mission.perception.detection.doubtful_altitude),
    }


def _outcomes(flights) -> str:
    """How the flights ended, e.g. "crashed 3, landed 19"."""
    outcomes = Counter(f["outcome"] for f in flights)
    return ", ".join(f"{key} {count}" for key, count in sorted(outcomes.items()))


def _mean(values) -> float:
    values = [v for v in values if v is not None and np.isfinite(v)]
    return statistics.fmean(values) if values else float("nan")


def _median(values) -> float:
    values = [v for v in values if v is not None and np.isfinite(v)]
    return statistics.median(values) if values else float("nan")


def _percentiles(seconds: list[float]) -> str:
    ms = np.array(seconds) * 1000.0
    return (f"median {np.median(ms):.2f} ms, p95 {np.percentile(ms, 95):.2f} ms, "
            f"slowest {ms.max():.2f} ms CPU")


def run_arms(mission: str, arms: dict[str, dict], seeds: range, workers: int):
    """{arm: [flight figures in seed order]} with every arm flown on every seed."""
    jobs = [(mission, overrides, seed) for overrides in arms.values() for seed in seeds]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        flights = list(pool.map(fly_one, jobs))
    n = len(seeds)
    return {arm: flights[k * n:(k + 1) * n] for k, arm in enumerate(arms)}


def _clearance_table(results, mission) -> None:
    """Each approach's lowest crossing over the true ground against the clearance the
    mission asks of both arms: clear_altitude_buffer (the thesis's z_buffer over the
    obstacle altitude, climbing by the distance for terrain rising at 45 degrees) and the
    trajectory's vertical margin over the mapped tops (k_sigma standard deviations up)."""
    buffer = mission.landing.clear_altitude_buffer
    margin = mission.landing.approach.vertical_margin
    required = {"clear_altitude": buffer, "trajectory": buffer if margin is None else margin}
    print("clearance over the true ground while crossing, per approach: lowest, 5th "
          "percentile, median (m), and approaches below the clearance the arm promises")
    for arm, flights in results.items():
        lows = np.array([c for f in flights for c in f["clearances"]])
        if not lows.size:
            continue
        below = int(np.sum(lows < required[arm]))
        print(f"  {arm:<16}{lows.size:>4} approaches: {lows.min():6.2f} "
              f"{np.percentile(lows, 5):6.2f} {np.median(lows):6.2f}; below "
              f"{required[arm]:g} m: {below}")


def _landed_by_one_arm(results) -> None:
    """Seeds only one arm landed on, and the exact two-sided sign test over them (the chance,
    were both arms equally likely to land, of a split at least this uneven)."""
    from scipy.stats import binomtest

    a, b = results["clear_altitude"], results["trajectory"]
    only_a = [x["seed"] for x, y in zip(a, b, strict=True)
              if x["outcome"] == "landed" != y["outcome"]]
    only_b = [y["seed"] for x, y in zip(a, b, strict=True)
              if y["outcome"] == "landed" != x["outcome"]]
    split = len(only_a) + len(only_b)
    p = binomtest(len(only_a), split).pvalue if split else 1.0
    print(f"landed by one arm only: clear_altitude {len(only_a)} {only_a}, trajectory "
          f"{len(only_b)} {only_b}; sign test p = {p:.2f}")


def approach_campaign(args) -> None:
    base = load_mission(args.mission)
    seeds = range(base.seed, base.seed + args.seeds)
    arms = {"clear_altitude": {"landing.approach.method": "clear_altitude"},
            "trajectory": {"landing.approach.method": "trajectory", **args.override}}
    wall = time.perf_counter()
    results = run_arms(args.mission, arms, seeds, args.workers)
    if args.save:
        Path(args.save).write_text(json.dumps(results, indent=1) + "\n")
    print(f"approach campaign: {Path(args.mission).name}, seeds {seeds.start}..{seeds.stop - 1}"
          f", {args.workers} workers, {time.perf_counter() - wall:.0f} s wall"
          + (f"; trajectory arm with {args.override}" if args.override else ""))
    print(f"{'method':<16}{'outcomes':<28}{'land s':>8}{'battery %':>10}{'Wh':>7}"
          f"{'tries':>6}{'jerk m/s3':>10}{'min clear m':>12}")
    for arm, flights in results.items():
        text = _outcomes(flights)
        print(f"{arm:<16}{text:<28}{_mean(f['time_to_land'] for f in flights):>8.1f}"
              f"{_mean(f['battery'] for f in flights):>10.1f}"
              f"{_mean(f['wh'] for f in flights):>7.1f}"
              f"{_mean(f['tries'] for f in flights):>6.1f}"
              f"{_median(f['peak_jerk'] for f in flights):>10.1f}"
              f"{min((c for f in flights for c in f['clearances']), default=np.nan):>12.2f}")
    _clearance_table(results, apply_overrides(base, arms["trajectory"]))
    _landed_by_one_arm(results)
    print("verification: tries that passed (share, 95 % interval by the normal approximation)")
    for arm, flights in results.items():
        tries = sum(f["tries"] or 0 for f in flights)
        passed = sum(f["verified"] for f in flights)
        share = passed / tries if tries else float("nan")
        half = 1.96 * (share * (1 - share) / tries) ** 0.5 if tries else float("nan")
        print(f"  {arm:<16}{passed} of {tries} ({100 * share:.0f} +- {100 * half:.0f} %)")
    print("  by the chosen site's record (first: from the cruise; doubtful: seen no lower than "
          "doubtful_altitude; high/low: seen from above/below it): tries, passed, safe by the "
          "ground truth, safe but failed")
    for arm, flights in results.items():
        kinds = Counter()
        for f in flights:
            for kind, safe, passed in f["tries_by_site"]:
                kinds[kind, "tries"] += 1
                kinds[kind, "passed"] += passed
                kinds[kind, "safe"] += safe
                kinds[kind, "rejected"] += safe and not passed
        print(f"  {arm:<16}" + "; ".join(
            f"{kind} {kinds[kind, 'tries']} {kinds[kind, 'passed']} {kinds[kind, 'safe']} "
            f"{kinds[kind, 'rejected']}" for kind in ("first", "doubtful", "high", "low")
            if kinds[kind, "tries"]))
    trajectory = results["trajectory"]
    mission = apply_overrides(base, arms["trajectory"])
    buffer = mission.landing.clear_altitude_buffer
    margin = mission.landing.approach.vertical_margin
    print(f"trajectory: {sum(f['flown'] for f in trajectory)} approaches flown along it, "
          f"{sum(f['fallbacks'] for f in trajectory)} handed to the clear altitude; margin over "
          f"the mapped tops {buffer if margin is None else margin:g} m, clear_altitude_buffer "
          f"{buffer:g} m")
    print("each approach and descent to a site (navigate_to_site start to verification start),"
          " mean s and battery %:")
    for arm, flights in results.items():
        parts = []
        for low, name in ((False, "from the cruise"), (True, "from a low hover")):
            got = [(d, e) for f in flights for lo, d, e in f["attempts"] if lo == low]
            if got:
                parts.append(f"{name} {len(got)}: {statistics.fmean(d for d, _ in got):.1f} s "
                             f"{statistics.fmean(e for _, e in got):.2f} %")
        print(f"  {arm:<16}" + "; ".join(parts))
    a, b = results["clear_altitude"], results["trajectory"]
    both = [(x, y) for x, y in zip(a, b, strict=True)
            if x["outcome"] == y["outcome"] == "landed"]
    print("per seed (clear_altitude | trajectory): outcome, time to land s, battery %, tries")
    for x, y in zip(a, b, strict=True):
        print(f"  seed {x['seed']:>3}: {x['outcome']:<8} {x['time_to_land'] or 0:6.1f} "
              f"{x['battery']:5.1f} {x['tries']!s:>3} | {y['outcome']:<8} "
              f"{y['time_to_land'] or 0:6.1f} {y['battery']:5.1f} {y['tries']!s:>3}")
    if both:
        dt = [y["time_to_land"] - x["time_to_land"] for x, y in both]
        de = [y["battery"] - x["battery"] for x, y in both]
        same = [(x, y) for x, y in both if x["tries"] == y["tries"]]
        print(f"paired, {len(both)} seeds both landed: trajectory - clear_altitude time to land "
              f"mean {statistics.fmean(dt):+.1f} s, battery {statistics.fmean(de):+.2f} %")
        if same:
            per_try = [(y["time_to_land"] - x["time_to_land"]) for x, y in same]
            print(f"  of which {len(same)} with as many tries in both: time "
                  f"{statistics.fmean(per_try):+.1f} s, battery "
                  f"{statistics.fmean(y['battery'] - x['battery'] for x, y in same):+.2f} %")
    plans = [t for f in b for t in f["plan_times"]]
    made = [t for f in b for t in f["trajectory_times"] if t > 0]
    if plans:
        print(f"planner, whole plan per site: {len(plans)} plans, {_percentiles(plans)}")
    if made:
        print(f"  of which trajectory generation: {len(made)} plans, {_percentiles(made)}")


# The descent-watch worlds: a flat 80 m square elevation model (0.25 m cells) with a 12 m
# tower east of home; a scripted site 0.3-0.9 m from its west face (seeded), so that a blind
# descent brushes the tower with the rotors (footprint radius 1 m); on odd seeds a flat world
# of the same size where a car drives a lane across the site's column instead.
CELL, SIDE = 0.25, 80.0
TOWER = (18.5, 22.5, -2.0, 2.0, 12.0)  # ENU x0, x1, y0, y1, height (m)


def _tower_world(directory: Path) -> Path:
    n = int(SIDE / CELL) + 1
    enu = np.arange(n) * CELL - SIDE / 2
    grid = np.zeros((n, n), np.float32)  # row i along +y (north), as .npy models are read
    x0, x1, y0, y1, height = TOWER
    grid[np.ix_((enu >= y0) & (enu <= y1), (enu >= x0) & (enu <= x1))] = height
    path = directory / "tower.npy"
    np.save(path, grid)
    return path


def watch_mission(seed: int, directory: Path, watch: bool, flow: dict, spare: bool = False):
    """The seed's scenario (see above) as a Mission, the watch on or off; with ``spare`` the
    LSM also holds a smaller site 10 m south-west of the waypoint, on open ground (where the
    tree goes when the first is banned)."""
    from autonomy.config import Mission

    rng = np.random.default_rng(seed)
    car = seed % 2 == 1
    gap = float(rng.uniform(0.3, 0.9))
    site = (TOWER[0] - gap, float(rng.uniform(-1.5, 1.5)))
    moving = None
    if car:
        # A car on a north-south lane through the column, at a seeded point of its round.
        lane = site[0] + float(rng.uniform(-0.5, 0.5))
        moving = {"paths": [{"kind": "vehicle", "path": [[lane, -15.0], [lane, 15.0]],
                             "speed": float(rng.uniform(2.0, 5.0)),
                             "start": float(rng.uniform(0.0, 30.0))}]}
    return Mission.model_validate({
        "name": "descent watch campaign", "cruise_altitude": 20.0,
        "waypoints": [[site[0] - 6.0, site[1], 20.0]],
        "landing": {"verify": False, "clear_altitude_buffer": 10.0,
                    "search_rectangle": [10.0, 10.0], "pattern_center_radius": 5.0,
                    "descent_watch": {"enabled": watch, "step": 2.0, "max_offset": 6.0}},
        "world": ({"kind": "flat", "size": [SIDE, SIDE], "cell_size": CELL,
                   "moving_obstacles": moving} if car else
                  {"kind": "file", "path": str(_tower_world(directory)),
                   "source_cell_size": CELL, "cell_size": CELL}),
        "sitl": {"wind": {"speed": 2.0, "direction": float(rng.uniform(0.0, 360.0))}},
        "perception": {"detector": "scripted", "rate": 2.0, "scripted": {"fov": 90.0},
                       "descent_flow": flow},
        "sites": [{"x": site[0], "y": site[1], "size": 4.0}] + (
            [{"x": site[0] - 12.0, "y": site[1] - 8.0, "size": 2.0}] if spare else []),
        "seed": seed, "time_limit": 150.0,
    })


def watch_thresholds(directory: Path) -> dict:
    """O_T and V_T of the default camera over an open column of the tower world."""
    from autonomy.perception.descent_flow import calibrate_descent
    from autonomy.perception.descent_flow_settings import DescentFlowSettings

    terrain = build_terrain(watch_mission(0, directory, True, {}), seed=0)
    o_t, v_t, _ = calibrate_descent(terrain, -20.0, 20.0, settings=DescentFlowSettings(),
                                    top=22.0)
    return {"obstacle_threshold": round(o_t, 2), "variance_threshold": round(v_t, 2)}


def fly_watch(job: tuple[int, bool, str, dict, bool]) -> dict:
    """One flight of the watch campaign (a worker process)."""
    seed, watch, directory, flow, spare = job
    mission = watch_mission(seed, Path(directory), watch, flow, spare)
    result = fly(mission)
    s = result.summary
    return {"seed": seed, "outcome": s["outcome"], "time_to_land": s.get("time_to_land"),
            "collisions": s.get("collisions") or 0, "touchdown_safe": s.get("touchdown_safe"),
            "flagged": sum(e.get("event") == "descent_obstacle" for e in result.events)}


def watch_campaign(args) -> None:
    import tempfile

    seeds = range(1, 1 + args.seeds)
    wall = time.perf_counter()
    with tempfile.TemporaryDirectory() as directory:
        flow = {**watch_thresholds(Path(directory)), **args.override}
        jobs = [(seed, watch, directory, flow, args.spare_site) for watch in (False, True)
                for seed in seeds]
        with ProcessPoolExecutor(max_workers=args.workers) as pool:
            flights = list(pool.map(fly_watch, jobs))
    n = len(seeds)
    print(f"descent watch campaign: seeds {seeds.start}..{seeds.stop - 1} (even: a 12 m tower "
          f"0.3-0.9 m beside the site; odd: a car driving across the site), {args.workers} "
          f"workers, {time.perf_counter() - wall:.0f} s wall; thresholds {flow}"
          + ("; a spare site 14 m away" if args.spare_site else ""))
    print(f"{'arm':<12}{'outcomes':<40}{'collisions':>11}{'flights hit':>12}"
          f"{'unsafe':>8}{'flagged':>9}{'land s':>8}")
    for k, arm in enumerate(("watch off", "watch on")):
        group = flights[k * n:(k + 1) * n]
        text = _outcomes(group)
        print(f"{arm:<12}{text:<40}{sum(f['collisions'] for f in group):>11}"
              f"{sum(f['collisions'] > 0 for f in group):>12}"
              f"{sum(f['touchdown_safe'] is False for f in group):>8}"
              f"{sum(f['flagged'] for f in group):>9}"
              f"{_mean(f['time_to_land'] for f in group):>8.1f}")
    print("per seed (off | on): outcome, collisions, touchdown safe, flagged pairs")
    for off, on in zip(flights[:n], flights[n:], strict=True):
        print(f"  seed {off['seed']:>3}: {off['outcome']:<8} {off['collisions']} "
              f"{off['touchdown_safe']!s:<5} {off['flagged']:>3} | {on['outcome']:<8} "
              f"{on['collisions']} {on['touchdown_safe']!s:<5} {on['flagged']:>3}")


def generation_benchmark(args) -> None:
    """CPU time of planning.min_snap.cruise_trajectory alone, over seeded approaches shaped
    like the campaign's (from a low hover or the cruise, 1 to 4 legs through a path's
    corners), within the default limits; each timed 15 times, the median kept."""
    from behaviors.settings import ApproachSettings

    limits = ApproachSettings()
    rng = np.random.default_rng(0)
    cases = []
    for _ in range(200):
        legs = int(rng.integers(1, 5))
        corners = np.cumsum(rng.uniform(-40.0, 40.0, (legs + 1, 3)), axis=0)
        corners[:, 2] = rng.uniform(5.0, 40.0, legs + 1)
        corners[0, 2] = rng.choice([2.5, 30.0])
        cases.append(corners)
    def generate(w):
        return planning_approach.cruise_trajectory(
            w, limits.max_speed, limits.max_acceleration, limits.max_climb_speed,
            limits.max_descent_speed)

    for w in cases[:20]:
        generate(w)  # warm the caches and imports
    per_case, pieces = [], []
    for w in cases:
        runs = []
        for _ in range(15):
            t0 = time.process_time()
            trajectory = generate(w)
            runs.append(time.process_time() - t0)
        per_case.append(statistics.median(runs))
        pieces.append(len(trajectory.durations))
    pieces = np.array(pieces)
    print(f"minimum-snap generation (cruise_trajectory), {len(cases)} approaches of 1 to 4 legs"
          f": {_percentiles(per_case)}")
    for low, high in ((1, 4), (5, 8), (9, 12), (13, 16), (17, 99)):
        inside = [c for c, n in zip(per_case, pieces, strict=True) if low <= n <= high]
        if inside:
            print(f"  {low:>2}-{high:<2} pieces: {len(inside):>3} approaches, median "
                  f"{np.median(inside) * 1e3:.3f} ms CPU")


def _override(text: str) -> tuple[str, object]:
    key, _, value = text.partition("=")
    try:
        parsed: object = float(value) if "." in value else int(value)
    except ValueError:
        parsed = {"true": True, "false": False}.get(value, value)
    return key, parsed


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--campaign", choices=("approach", "watch", "generation"),
                        default="approach")
    parser.add_argument("--mission", default=str(ROOT / "missions" / "mars_demo.yaml"),
                        help="the approach campaign's mission")
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--spare-site", action="store_true",
                        help="watch campaign: the LSM also holds a smaller site on open ground, "
                        "where the tree goes once the watch has banned the first")
    parser.add_argument("--save", metavar="PATH",
                        help="approach campaign: write every flight's figures to PATH (JSON)")
    parser.add_argument("--set", dest="override", action="append", type=_override,
                        default=[], metavar="KEY=VALUE",
                        help="a mission override for the new arm only (trajectory / watch on)")
    args = parser.parse_args()
    args.override = dict(args.override)
    if args.campaign == "approach":
        approach_campaign(args)
    elif args.campaign == "generation":
        generation_benchmark(args)
    else:
        watch_campaign(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
