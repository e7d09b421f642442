"""Benchmark of the terrain worlds and the depth camera.

Prints, per world kind, the generation time of the default 400 m x 400 m world at 0.2 m
cells (median over seeds), the time of the ground-truth safety map of the whole world and
its safe fraction (footprint and clearance disks of ``SafetySettings()``), the median time
of one 256 x 256 depth render at several altitudes above ground (SfM above 15 m, stereo
below), and the time of ``is_safe`` on 1, 300 and 10000 scattered points of the Mars world.
Each figure is wall time / process CPU time in milliseconds (CPU time sums all threads; on a
loaded machine it is the steadier figure).
OpenCV and BLAS run on one thread, as in ``bench_lsd.py``.

    .venv/bin/python benchmarks/bench_terrain.py [--repeats N] [--generate-only]
"""

from __future__ import annotations

import argparse
import os
import time

import _checkout  # noqa: F401  (this checkout's packages first)

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from sitl.sensors import DepthCamera, DepthCameraSettings  # noqa: E402
from sitl.terrain import Terrain, is_safe, make_terrain, safety_map  # noqa: E402

KINDS = ("flat", "mars", "urban", "rubble")
ALTITUDES = (100.0, 30.0, 10.0, 2.5)


def median_ms(fn, repeats: int) -> tuple[float, float]:
    """Median wall and CPU milliseconds of ``fn(k)`` for k = 0 .. repeats-1."""
    wall, cpu = [], []
    for k in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn(k)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    return 1e3 * float(np.median(wall)), 1e3 * float(np.median(cpu))


def fmt(figure: tuple[float, float]) -> str:
    return f"{figure[0]:.0f}/{figure[1]:.0f}"


def render_times(terrain: Terrain, altitude: float, repeats: int) -> tuple[float, float]:
    """Median time of one render at ``altitude`` m above ground at random places."""
    camera = DepthCamera(terrain, DepthCameraSettings(), rng=np.random.default_rng(1))
    rng = np.random.default_rng(2)

    def render(k: int) -> None:
        x, y = rng.uniform(-150, 150, 2)
        z = float(terrain.height(x, y)) + altitude
        # SfM needs lateral motion: 15 m within the last 2 s.
        camera.observe_pose([x - 15.0, y, z], 0.0, 10.0 * k)
        assert camera.render([x, y, z], 0.0, 10.0 * k + 1.0) is not None

    render(-1)  # builds the empty-space bounds, once per terrain
    return median_ms(render, repeats)


def main() -> None:
    parser = argparse.ArgumentParser(description="terrain and depth camera benchmark")
    parser.add_argument("--repeats", type=int, default=5, help="runs per figure")
    parser.add_argument("--generate-only", action="store_true",
                        help="only the generation column (world generation before/after)")
    args = parser.parse_args()
    cv2.setNumThreads(1)
    if args.generate_only:
        print(f"world generation, 400 m x 400 m at 0.2 m cells: wall/CPU ms, median of "
              f"{args.repeats} seeds after a first world")
        for kind in KINDS:
            make_terrain({"kind": kind}, seed=99)  # compiled kernels loaded, caches filled
            generate = median_ms(
                lambda k, kind=kind: make_terrain({"kind": kind}, seed=k), args.repeats
            )
            print(f"{kind:>10s} {fmt(generate):>12s}")
        return
    print(
        "400 m x 400 m worlds at 0.2 m cells (2001 x 2001); figures are wall/CPU ms, "
        f"median of {args.repeats}"
    )
    columns = ["kind", "generate", "safety map", "safe %"] + [f"render@{a:g}m" for a in ALTITUDES]
    print("".join(f"{c:>13s}" for c in columns))
    for kind in KINDS:
        generate = median_ms(
            lambda k, kind=kind: make_terrain({"kind": kind}, seed=k), args.repeats
        )
        terrain = make_terrain({"kind": kind}, seed=0)
        masks = []
        safety = median_ms(lambda k, t=terrain, m=masks: m.append(safety_map(t)[0]), args.repeats)
        renders = [render_times(terrain, a, args.repeats) for a in ALTITUDES]
        cells = [kind, fmt(generate), fmt(safety), f"{100 * masks[0].mean():.1f}"]
        print("".join(f"{c:>13s}" for c in cells + [fmt(r) for r in renders]))
    terrain = make_terrain({"kind": "mars"}, seed=0)
    # few scattered points are judged on a patch each, many on one map of their window
    for count in (1, 300, 10_000):
        points = np.random.default_rng(3).uniform(-190, 190, (2, count))
        wall, cpu = median_ms(lambda k, p=points: is_safe(terrain, p[0], p[1]), args.repeats)
        print(
            f"is_safe on mars, {count} points: {wall:.1f}/{cpu:.1f} ms "
            f"({1e3 * wall / count:.0f} us/point wall)"
        )


if __name__ == "__main__":
    main()
