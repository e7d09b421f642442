"""The elevation map's update and the site detection per frame, on a real flight's frames.

Flies a mission once (``autonomy.runner.fly``) keeping every depth frame the elevation
detector receives, then replays those frames through a fresh detector and times
``integrate`` (the map update) and ``detect`` (the analysis) per frame in CPU time of the
calling thread, by the camera's height band (the fine map is analysed below 20 m AGL, frames
come four times a second below 15 m), and the parts of a low frame's detection. The replay
is warmed up on the first frames first, so one-time costs (numba's start-up and its cache
loads) are printed apart.

With ``--before OLD_CHECKOUT`` the same frames are replayed alternately by that checkout and
this one, each in its own process, and the figures printed side by side; the sites each
reports for each frame must be the same (checked, printed).

Run: .venv/bin/python benchmarks/bench_elevation.py [--mission missions/mars_science.yaml]
     [--seed 0] [--rounds 2] [--before /path/to/old/checkout]
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
from replay_compare import (
    print_header,
    print_row,
    replay_alternately,
    replay_arguments,
    timed,
)

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("fit_planes", "step_hazards", "step_levels", "safe_mask", "site_size", "step_room",
         "step_room_at", "select_sites", "rank_sites", "obstacle_altitude", "maximum_box",
         "_largest_within", "pooled_level")


def record(mission_file: Path, seed: int, out: Path) -> int:
    """Fly the mission, pickle the detector's settings and every frame it got into ``out``."""
    from autonomy.config import load_mission
    from autonomy.runner import fly
    from lsd.elevation.detector import ElevationDetector

    frames = []
    original = ElevationDetector.process

    def keep(self, frame):
        frames.append(frame)
        return original(self, frame)

    ElevationDetector.process = keep
    try:
        mission = load_mission(mission_file)
        fly(mission, seed=seed)
    finally:
        ElevationDetector.process = original
    p = mission.perception
    out.write_bytes(pickle.dumps((p.elevation_map, p.detection, frames)))
    return len(frames)


def replay(frames_file: Path, warm: int = 8) -> dict:
    """Replay the frames: CPU ms per frame by band, the parts of the low frames' detection
    (a second replay, with the parts wrapped), the warm-up's cost and a digest of the sites."""
    import numpy as np

    import lsd.elevation.detector as detector_module

    map_settings, settings, frames = pickle.loads(frames_file.read_bytes())

    def run(frames, on_detect=None):
        det = detector_module.ElevationDetector(map_settings, settings)
        cost = defaultdict(lambda: [0, 0.0, 0.0])
        digest = hashlib.sha256()
        for frame in frames:
            start = time.thread_time()
            ok = det.integrate(frame)
            mid = time.thread_time()
            sites = det.detect(np.asarray(frame.position, float), float(frame.timestamp),
                               frame.source) if ok else []
            end = time.thread_time()
            band = "below 20 m AGL (fine map)" if det.low else "20 m AGL and above"
            c = cost[band]
            c[0] += 1
            c[1] += 1e3 * (mid - start)
            c[2] += 1e3 * (end - mid)
            if on_detect is not None:
                on_detect(det.low and ok)
            digest.update(repr([(s.x, s.y, s.z, s.roughness, s.uncertainty, s.size,
                                 s.obstacle_altitude, s.observation_altitude) for s in sites])
                          .encode())
        return cost, digest.hexdigest()

    start = time.thread_time()
    run(frames[:warm])  # one-time costs (compiled kernels' start-up and cache loads)
    warm_up = 1e3 * (time.thread_time() - start)
    cost, digest = run(frames)

    # The parts of the low frames' detection.
    spent: dict[str, float] = defaultdict(float)
    low_parts: dict[str, float] = defaultdict(float)
    low_frames = [0]

    def timed_part(name, fn):
        def add(ms, name=name):
            spent[name] += ms
        return timed(fn, add)

    for name in PARTS:
        if hasattr(detector_module, name):
            setattr(detector_module, name, timed_part(name, getattr(detector_module, name)))

    def on_detect(low):
        if low:
            low_frames[0] += 1
            for k, v in spent.items():
                low_parts[k] += v
        spent.clear()

    original_integrate = detector_module.ElevationDetector.integrate

    def integrate(self, frame):  # parts timed inside the update do not count
        try:
            return original_integrate(self, frame)
        finally:
            spent.clear()

    detector_module.ElevationDetector.integrate = integrate
    run(frames, on_detect)
    n = max(low_frames[0], 1)
    return {
        "warm_up_ms": warm_up,
        "bands": {k: [v[0], v[1] / v[0], v[2] / v[0]] for k, v in cost.items()},
        "low_parts": {k: v / n for k, v in low_parts.items()},
        "sites_sha256": digest,
    }


def main(argv: list[str] | None = None) -> int:
    parser = replay_arguments(__doc__.splitlines()[0])
    args = parser.parse_args(argv)
    if args.replay is not None:  # the child process of a comparison
        print(json.dumps(replay(args.replay)))
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        frames_file = Path(tmp) / "frames.pkl"
        n = record(args.mission, args.seed, frames_file)
        results = replay_alternately(__file__, frames_file, args.before, args.rounds)
    load = os.getloadavg()[0]
    print(f"== {args.mission.name} seed {args.seed}: {n} frames, {args.rounds} rounds, "
          f"load average {load:.2f}")
    names = list(results)
    digests = {r["sites_sha256"] for name in names for r in results[name]}
    print(f"sites per frame: {'the same' if len(digests) == 1 else 'DIFFERENT'} in every replay")
    print_header("CPU ms per frame", names)
    row = print_row
    bands = sorted(results[names[0]][0]["bands"])
    for band in bands:
        count = results[names[0]][0]["bands"][band][0]
        for index, what in ((1, "map update"), (2, "detection")):
            values = [min(r["bands"][band][index] for r in results[name]) for name in names]
            row(f"{what}, {band}, {count}", values)
    print("  low frames' detection by part (min over rounds):")
    parts = sorted({k for name in names for r in results[name] for k in r["low_parts"]})
    for part in parts:
        row(f"  {part}", [min(r["low_parts"].get(part, 0.0) for r in results[name])
                          for name in names])
    row("warm-up: first 8 frames, one-time costs", [
        min(r["warm_up_ms"] for r in results[name]) for name in names])
    return 0 if len(digests) == 1 else 1


if __name__ == "__main__":
    sys.exit(main())
