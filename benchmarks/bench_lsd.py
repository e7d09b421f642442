"""Benchmark of the elevation-map landing-site detector on the simulated depth camera.

1. Speed: median milliseconds per 256 x 256 depth frame through render, then map update +
   detection (LSD), and both, at several altitudes above ground of the Mars world (wall /
   process CPU time; on a loaded machine CPU time is the steadier figure), beside seed
   003's reported 167.5 ms per 640 x 480 frame for its detector. BLAS and OpenCV are
   limited to one thread, as the target is one core.
2. Precision by altitude band on the Mars world, flown like a mission: a cruise pass at
   100 m (structure from motion), then a stereo descent from 20 m to the verification
   altitude (2.5 m) and a short hover there over each of the best sites the pass found.
   Every observation is judged by the ground-truth safety (``sitl.terrain.is_safe``) at its
   position and binned by its observation altitude (the altitude a verification would
   credit it with). The defaults give well over 100 observations below 5 m, where at least
   99% must be safe.

Targets (issue 5), checked and printed: the LSD (map update + detection) at most 10 ms
median CPU per frame at every altitude, render + LSD under 20 ms, and at least 99% of the
observations below 5 m safe.

    .venv/bin/python benchmarks/bench_lsd.py [--seeds 5] [--sites 10] [--repeats 15]
        [--focal-px 256]
"""

from __future__ import annotations

import os

import _checkout  # noqa: F401  (this checkout's packages first)

# One core: keep BLAS from spreading (or spinning) over threads; set before numpy loads.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from autonomy.perception.camera import to_depth_frame  # noqa: E402
from lsd.elevation.detector import ElevationDetector  # noqa: E402
from lsd.elevation.settings import DetectorSettings  # noqa: E402
from lsm.records import SiteObservation  # noqa: E402
from sitl.sensors import DepthCamera, DepthCameraSettings  # noqa: E402
from sitl.terrain import Terrain, is_safe, make_terrain  # noqa: E402

BANDS = ((0.0, 5.0), (5.0, 20.0), (20.0, 60.0), (60.0, float("inf")))
SEED003_MS = 167.5  # seed 003, table I: per 640 x 480 frame, its costmap detector
# Heights above the site, one frame each (2 Hz): the descent, then the verification hover.
DESCENT = (20.0, 16.0, 13.0, 11.0, 9.0, 7.5, 6.0, 5.0, 4.2, 3.5, 3.0, 2.7) + (2.5,) * 8
LSD_TARGET_MS = 10.0  # map update + detection, median CPU per frame, every altitude
TOTAL_TARGET_MS = 20.0  # render + map update + detection
LOW_PRECISION = 0.99  # share of the observations below 5 m that must be safe


def frame_times(
    terrain: Terrain, agl: float, repeats: int, camera_settings: DepthCameraSettings
) -> dict[str, float]:
    """Median ms of one frame at ``agl`` over the terrain, flying east at 8 m/s (2 Hz
    frames): render (wall and CPU), detector update + detection (wall and CPU), their sum,
    and the median number of sites per frame."""
    camera = DepthCamera(terrain, camera_settings, rng=np.random.default_rng(1))
    detector = ElevationDetector()
    rows = []
    for k in range(-2, repeats):  # two warm-up frames (SfM baseline, allocations)
        x = -40.0 + 4.0 * k
        z = float(terrain.height(x, 10.0)) + agl
        w0, c0 = time.perf_counter(), time.process_time()
        rendered = camera.render([x, 10.0, z], 0.0, 0.5 * (k + 2))
        w1, c1 = time.perf_counter(), time.process_time()
        observations = detector.process(to_depth_frame(rendered)) if rendered else []
        w2, c2 = time.perf_counter(), time.process_time()
        if k >= 0 and rendered is not None:
            rows.append((w1 - w0, c1 - c0, w2 - w1, c2 - c1, w2 - w0, c2 - c0, len(observations)))
    med = np.median(np.array(rows), axis=0)
    analysis = detector.last_analysis
    keys = ("render_wall", "render_cpu", "lsd_wall", "lsd_cpu", "total_wall", "total_cpu")
    out = {key: 1e3 * float(v) for key, v in zip(keys, med[:6], strict=True)}
    out["sites"] = float(med[6])
    out["cell"] = analysis.resolution if analysis is not None else float("nan")
    return out


def fly_and_judge(
    terrain: Terrain, seed: int, n_sites: int, camera_settings: DepthCameraSettings
) -> list[tuple[float, bool]]:
    """Cruise pass then descents over the best sites; (observation altitude, safe) pairs."""
    rng = np.random.default_rng(seed)
    camera = DepthCamera(terrain, camera_settings, rng=rng)
    detector = ElevationDetector()
    judged: list[tuple[float, bool]] = []
    t = 0.0

    def look(position) -> list[SiteObservation]:
        rendered = camera.render(position, 0.0, t)
        observations = detector.process(to_depth_frame(rendered)) if rendered else []
        if observations:
            safe = is_safe(terrain, [o.x for o in observations], [o.y for o in observations])
            judged.extend(
                (o.observation_altitude, bool(s)) for o, s in zip(observations, safe, strict=True)
            )
        return observations

    y0 = float(rng.uniform(-60, 60))
    candidates: dict[tuple[float, float], SiteObservation] = {}
    for k in range(30):  # 120 m at 8 m/s, 2 Hz, 100 m above home
        t += 0.5
        for o in look([-60.0 + 4.0 * k, y0, 100.0]):
            candidates[(o.x, o.y)] = o
    # The best sites of the pass, as a mission would rank them (loss terms of eq. 3.1).
    ranked = sorted(candidates.values(), key=lambda o: o.roughness + o.uncertainty - o.size / 10.0)
    chosen: list[SiteObservation] = []
    for o in ranked:
        if all(np.hypot(o.x - c.x, o.y - c.y) > 10.0 for c in chosen):
            chosen.append(o)
        if len(chosen) == n_sites:
            break
    for site in chosen:
        for height in DESCENT:
            t += 0.5
            look([site.x, site.y, site.z + height])
        t += 60.0  # fly on: the low-altitude cells age out before the next descent
    return judged


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5, help="Mars worlds flown")
    parser.add_argument("--sites", type=int, default=10, help="descents per world")
    parser.add_argument("--repeats", type=int, default=15, help="frames timed per altitude")
    parser.add_argument("--focal-px", type=float, default=256.0, help="camera focal length")
    args = parser.parse_args()
    cv2.setNumThreads(1)

    terrain = make_terrain({"kind": "mars", "size": [300.0, 300.0]}, seed=11)
    camera = DepthCameraSettings(focal_px=args.focal_px)
    print(
        f"elevation-map LSD, 256 x 256 depth frames (f = {args.focal_px:.0f} px), Mars world; "
        "map 80 m at 0.25 m, below 20 m AGL 32 m at 0.1 m; analysed in cells pooled up to "
        f"{100 * DetectorSettings().analysis_cell_ratio:.0f}% of the height (cell m)"
    )
    print("median ms per frame, wall/CPU (CPU: this process; on a loaded machine the steadier)")
    print("total = render + LSD (LSD = map update + detection)")
    print(
        f"{'AGL m':>6} {'source':>7} {'render':>11} {'LSD':>11} {'total':>11} {'sites':>6} "
        f"{'cell m':>6}"
    )
    worst_lsd = (0.0, 0.0)  # (ms, AGL)
    worst_total = (0.0, 0.0)
    for agl, source in ((100.0, "sfm"), (30.0, "sfm"), (10.0, "stereo"), (2.5, "stereo")):
        t = frame_times(terrain, agl, args.repeats, camera)
        render = f"{t['render_wall']:5.1f}/{t['render_cpu']:<5.1f}"
        lsd = f"{t['lsd_wall']:5.1f}/{t['lsd_cpu']:<5.1f}"
        total = f"{t['total_wall']:5.1f}/{t['total_cpu']:<5.1f}"
        print(f"{agl:6.1f} {source:>7} {render} {lsd} {total} {t['sites']:6.0f} {t['cell']:6.2f}")
        worst_lsd = max(worst_lsd, (t["lsd_cpu"], agl))
        worst_total = max(worst_total, (t["total_cpu"], agl))
    print(f"seed 003 (costmap detector, 640 x 480 frame): {SEED003_MS} ms per frame")
    for name, target, (worst, agl) in (
        ("LSD", LSD_TARGET_MS, worst_lsd),
        ("total", TOTAL_TARGET_MS, worst_total),
    ):
        verdict = "met" if worst <= target else "NOT met"
        print(
            f"target {name} <= {target:.0f} ms median CPU per frame at every altitude: "
            f"{verdict} (slowest {worst:.1f} ms at {agl:.1f} m)"
        )
    print()

    judged: list[tuple[float, bool]] = []
    for seed in range(args.seeds):
        world = make_terrain({"kind": "mars", "size": [300.0, 300.0]}, seed=100 + seed)
        judged += fly_and_judge(world, seed, args.sites, camera)
    altitude = np.array([a for a, _ in judged])
    safe = np.array([s for _, s in judged], dtype=bool)
    print(
        f"precision against ground truth, Mars worlds x{args.seeds}, cruise pass + "
        f"{args.sites} descents each"
    )
    print(f"{'observation altitude':>21} {'observations':>13} {'precision':>10}")
    for lo, hi in BANDS:
        band = (altitude >= lo) & (altitude < hi)
        label = f"{lo:.0f}-{hi:.0f} m" if np.isfinite(hi) else f">{lo:.0f} m"
        if lo == 0.0:
            label = f"<{hi:.0f} m"
        share = f"{100.0 * safe[band].mean():.1f}%" if band.any() else "-"
        print(f"{label:>21} {int(band.sum()):13d} {share:>10}")
    low = altitude < BANDS[0][1]
    if low.any():
        met = safe[low].mean() >= LOW_PRECISION
        print(
            f"requirement >= {100 * LOW_PRECISION:.0f}% safe below {BANDS[0][1]:.0f} m: "
            f"{'met' if met else 'NOT met'} ({100.0 * safe[low].mean():.1f}% of {int(low.sum())})"
        )
    else:
        print(f"requirement >= {100 * LOW_PRECISION:.0f}% safe below 5 m: no observation there")


if __name__ == "__main__":
    main()
