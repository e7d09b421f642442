"""The depth camera's render per frame, on a real flight's renders.

Flies a mission once (``autonomy.runner.fly``) keeping every call of
``DepthCamera.render`` (pose, time, AGL, ground region) with the camera's state before it
(its noise generator, depth source and SfM pose history), then replays those renders on a
copy of the camera and times each in CPU time of the calling thread, by camera height
(cruise, the stereo band, below 15 m where frames come four times a second), and the parts
of a render (a replay with the parts wrapped). The one-time costs are printed apart: per
process (numba's cache loads) and per flight (the levels of detail and their height bounds,
built once per world), each as what a replay paying it took more than one that did not.

With ``--before OLD_CHECKOUT`` the same renders are replayed alternately by that checkout and
this one, each in its own process, and the figures printed side by side; every frame's
depth, sigma and rendered mask must be the same bit for bit (checked, printed).

Run: .venv/bin/python benchmarks/bench_render.py [--mission missions/mars_science.yaml]
     [--seed 0] [--rounds 2] [--before /path/to/old/checkout]
"""

from __future__ import annotations

import copy
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
# (module, attribute) of the parts of a render timed in the second replay.
PARTS = (
    ("sitl.sensors.march", "tile_brackets"),
    ("sitl.sensors.march", "march_rays"),
    ("sitl.sensors.raycast", "tiles_needed"),
    ("sitl.sensors.raycast", "pixels_needed"),
    ("sitl.sensors.camera", "_deviates"),
    ("sitl.sensors.camera", "_sigma_and_noise"),
)
BANDS = ("50 m AGL and above", "15 to 50 m AGL", "below 15 m AGL")


def record(mission_file: Path, seed: int, out: Path) -> int:
    """Fly the mission, pickle a copy of the camera as the first render found it and every
    render call with the camera's state before it into ``out``."""
    from autonomy.config import load_mission
    from autonomy.runner import fly
    from sitl.sensors.camera import DepthCamera

    calls = []
    first = []
    original = DepthCamera.render

    def keep(self, position, yaw, timestamp, agl=None, region=None):
        if not first:
            first.append(copy.deepcopy(self))
        calls.append((position, yaw, timestamp, agl, region, self.rng.bit_generator.state,
                      self.selector.source, list(self._history), self._last_skip))
        return original(self, position, yaw, timestamp, agl=agl, region=region)

    DepthCamera.render = keep
    try:
        fly(load_mission(mission_file), seed=seed)
    finally:
        DepthCamera.render = original
    out.write_bytes(pickle.dumps((first[0], calls)))
    return len(calls)


def replay(calls_file: Path) -> dict:
    """Replay the renders: on the recorded camera (paying the process's and the flight's
    one-time costs), on a copy of it (the flight's: its levels of detail and their height
    bounds), on that copy again timed by band, and again timed by part (wrapped); the
    one-time costs (the differences) and a digest of the frames."""
    import importlib
    from collections import deque

    import numpy as np

    first_camera, calls = pickle.loads(calls_file.read_bytes())
    camera = copy.deepcopy(first_camera)  # a second flight over the same world
    current = [BANDS[0]]  # the band of the render being replayed

    def run(calls, camera):
        cost = defaultdict(lambda: [0, 0.0, 0.0])
        digest = hashlib.sha256()
        for position, yaw, timestamp, agl, region, state, source, history, skip in calls:
            camera.rng.bit_generator.state = state
            camera.selector.source = source
            camera._history = deque(history)
            camera._last_skip = skip
            height = camera.rangefinder.true_agl(np.asarray(position, dtype=np.float64))
            band = BANDS[0] if height >= 50 else BANDS[1] if height >= 15 else BANDS[2]
            current[0] = band
            start = time.thread_time()
            frame = camera.render(position, yaw, timestamp, agl=agl, region=region)
            spent = 1e3 * (time.thread_time() - start)
            c = cost[band]
            c[0] += 1
            c[1] += spent
            if frame is None:
                digest.update(b"none")
                continue
            c[2] += 1.0 if frame.rendered is None else float(frame.rendered.mean())
            for a in (frame.depth, frame.sigma, frame.rendered):
                digest.update(b"-" if a is None else np.ascontiguousarray(a).tobytes())
        return cost, digest.hexdigest()

    def summed(cost):
        return sum(v[1] for v in cost.values())

    first = summed(run(calls, first_camera)[0])  # with the process's and the flight's
    second = summed(run(calls, camera)[0])  # with the flight's one-time costs only
    cost, digest = run(calls, camera)

    spent: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))

    def timed_part(name, fn):
        def add(ms, name=name):
            spent[current[0]][name] += ms
        return timed(fn, add)

    for module, name in PARTS:
        owner = importlib.import_module(module)
        if hasattr(owner, name):
            setattr(owner, name, timed_part(name, getattr(owner, name)))
    parts_cost, _ = run(calls, camera)
    parts = {}
    for band, (n, total, _) in parts_cost.items():
        parts[band] = {k: v / n for k, v in spent[band].items()}
        parts[band]["rest of render"] = total / n - sum(parts[band].values())
    return {
        "per_process_ms": first - second,
        "per_flight_ms": second - summed(cost),
        "bands": {k: [v[0], v[1] / v[0], v[2] / v[0]] for k, v in cost.items()},
        "parts": parts,
        "frames_sha256": digest,
    }


def main(argv: list[str] | None = None) -> int:
    parser = replay_arguments(__doc__.splitlines()[0])
    parser.add_argument("--calls", type=Path, default=None,
                        help="replay these recorded renders (written there if missing)")
    args = parser.parse_args(argv)
    if args.replay is not None:  # the child process of a comparison
        print(json.dumps(replay(args.replay)))
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        calls_file = args.calls or Path(tmp) / "renders.pkl"
        if calls_file.exists():
            n = len(pickle.loads(calls_file.read_bytes())[1])
        else:
            n = record(args.mission, args.seed, calls_file)
        results = replay_alternately(__file__, calls_file, args.before, args.rounds)
    load = os.getloadavg()[0]
    print(f"== {args.mission.name} seed {args.seed}: {n} renders, {args.rounds} rounds, "
          f"load average {load:.2f}")
    names = list(results)
    digests = {r["frames_sha256"] for name in names for r in results[name]}
    print(f"frames: {'the same' if len(digests) == 1 else 'DIFFERENT'} in every replay")
    print_header("CPU ms per render (min over rounds)", names)
    row = print_row
    first = results[names[0]][0]["bands"]
    for band in (b for b in BANDS if b in first):
        count, _, share = first[band]
        values = [min(r["bands"][band][1] for r in results[name]) for name in names]
        row(f"{band}, {count} ({100 * share:.0f} % of pixels)", values)
    counts = [first[b][0] for b in first]
    row("all renders (mean)", [
        min(sum(r["bands"][b][0] * r["bands"][b][1] for b in first) / sum(counts)
            for r in results[name]) for name in names])
    for band in (b for b in BANDS if b in first):
        print(f"  parts, {band} (min over rounds):")
        parts = sorted({k for name in names for r in results[name]
                        for k in r["parts"].get(band, {})})
        for part in parts:
            row(f"  {part}", [min(r["parts"].get(band, {}).get(part, 0.0)
                                  for r in results[name]) for name in names])
    print("  one-time costs, ms (min over rounds):")
    row("  per flight (levels of detail, height bounds)", [
        min(r["per_flight_ms"] for r in results[name]) for name in names])
    row("  per process (compiled kernels' loads)", [
        min(r["per_process_ms"] for r in results[name]) for name in names])
    return 0 if len(digests) == 1 else 1


if __name__ == "__main__":
    sys.exit(main())
