"""Benchmark of the moving obstacles (issue 18 part 4): what they add to the sensors and to
a flight.

Prints, on an urban world of 400 m x 400 m at 0.2 m cells seen by the mission-default
256 x 256 depth camera (f = 256 px) from 30 m: the median time of one depth render without
moving obstacles, with 50 random ones in the world and with 20 crowded within 15 m of the
view's centre (all in view), and the ratio to the first; the time to place all obstacles
at one instant (``MovingObstacles.at``); and one lockstep flight of the small elevation-map
mission of tests/e2e/test_moving_obstacles_flight.py with and without a person walking
far from everything (same sites, same landing), so the difference is the per-tick
collision check and the sensors' extra tests. Each time is wall / process CPU
milliseconds (on a loaded machine CPU is the steadier figure).

    .venv/bin/python benchmarks/bench_moving.py [--repeats N]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
import numpy as np

from sitl.sensors import DepthCamera, DepthCameraSettings
from sitl.terrain import make_terrain

WORLD = {"kind": "urban", "size": [400.0, 400.0], "cell_size": 0.2}
VIEW = (20.0, -10.0, 30.0)  # camera above (x, y) at 30 m


def timed(fn, repeats: int) -> tuple[float, float]:
    """Median wall and CPU milliseconds of ``fn(k)``."""
    wall, cpu = [], []
    for k in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn(k)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return 1e3 * float(np.median(wall)), 1e3 * float(np.median(cpu))


def render_times(repeats: int) -> None:
    worlds = {
        "none": WORLD,
        "50 in the world": {**WORLD, "moving_obstacles": {"count": 50}},
        "20 in view": {**WORLD, "moving_obstacles": {
            "count": 20, "area": [VIEW[0], VIEW[1], 15.0], "path_length": [10.0, 30.0]}},
    }
    base = None
    for name, settings in worlds.items():
        terrain = make_terrain(settings, seed=3)
        camera = DepthCamera(terrain, DepthCameraSettings(  # stereo depth at 30 m
            noise=False, stereo_below=100.0, sfm_above=100.0, stereo_max_range=100.0))
        x, y, _ = VIEW
        z = VIEW[2]
        position = (x, y, float(terrain.height(x, y)) + z)
        camera.render(position, 0.0, 0.0, agl=z)  # build the height bounds first
        # a new instant each frame (the obstacles' places are not reused)
        wall, cpu = timed(lambda k, c=camera, p=position: c.render(p, 0.0, 0.1 * (k + 1),
                                                                   agl=VIEW[2]), repeats)
        frame = camera.render(position, 0.0, 1.0, agl=z)
        seen = 0 if frame.moving is None else len(np.unique(frame.moving[1][
            frame.moving[1] >= 0]))
        base = base or cpu
        print(f"depth render 256 x 256 from 30 m, moving obstacles {name:>15}: "
              f"{wall:6.2f} / {cpu:6.2f} ms ({cpu / base:4.2f}x), {seen} in view")
        if terrain.moving is not None and name == "50 in the world":
            wall, cpu = timed(lambda k, m=terrain.moving: m.at(0.37 * k), repeats * 10)
            print(f"placing {len(terrain.moving)} obstacles at one instant: "
                  f"{1e3 * wall:6.1f} / {1e3 * cpu:6.1f} us")


def flight_times(repeats: int) -> None:
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "e2e"))
    from test_moving_obstacles_flight import MISSION

    from autonomy.config import parse_mission
    from autonomy.runner import fly

    still = MISSION.replace("FRESH", "false").split("  moving_obstacles:")[0] + MISSION.split(
        "speed: 1.0, once: true}]\n")[1]
    far = MISSION.replace("FRESH", "false").replace("-15.0], [-0.25, -0.25]]",
                                                    "-50.0], [-0.25, -40.0]]")
    results = {}
    for name, text in (("no moving obstacles", still), ("a person far away", far)):
        mission = parse_mission(text, "bench.yaml")
        outcome = []
        wall, cpu = timed(lambda k, m=mission, o=outcome: o.append(fly(m).summary), repeats)
        results[name] = cpu
        s = outcome[-1]
        print(f"flight ({name:>19}): {wall:7.1f} / {cpu:7.1f} ms, outcome {s['outcome']}, "
              f"{s['mission_time']:.1f} s simulated, touchdown ({s['touchdown']['x']:.2f}, "
              f"{s['touchdown']['y']:.2f})")
    a, b = results.values()
    print(f"flight CPU with / without: {b / a:.2f}x")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    render_times(args.repeats)
    flight_times(max(3, args.repeats // 5))


if __name__ == "__main__":
    main()
