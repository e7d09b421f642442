"""Big LiDAR tiles in bounded memory: ``lander detect --lidar`` on a synthetic classified
urban LAZ of 20 million points (written to a temporary file in chunks), streamed through
200 m tiles; and, on a 2 million point cloud both can handle, the whole-cloud run against
the streamed one (same sites, memory and time side by side). Each run is a separate
``lander`` process, its peak memory read from the kernel (ru_maxrss of the child).

    python benchmarks/bench_lidar_big.py [--points 20000000] [--small 2000000]
"""

from __future__ import annotations

import argparse
import csv
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
import laspy
import numpy as np

from lsd.lidar_pca.scenes import scene

DENSITY = 16.0  # points per m^2, a dense airborne survey
BLOCK = 100.0  # m: the scene is written a block at a time


def write_scene(path: Path, points: int, seed: int = 0) -> float:
    """An urban LAZ of about ``points`` points, blocks of BLOCK m written one at a time
    (memory bounded by a block); returns the side (m)."""
    side = math.sqrt(points / DENSITY)
    blocks = max(1, math.ceil(side / BLOCK))
    edge = side / blocks
    header = laspy.LasHeader(point_format=6, version="1.4")
    header.scales = np.full(3, 0.001)
    header.offsets = np.array([500_000.0, 4_000_000.0, 0.0])
    from pyproj import CRS

    header.add_crs(CRS.from_epsg(32633))
    with laspy.open(path, mode="w", header=header) as writer:
        for k in range(blocks * blocks):
            i, j = divmod(k, blocks)
            pts, cls = scene("urban", size=edge, density=DENSITY, seed=seed + k)
            pts[:, 0] += 500_000.0 + i * edge
            pts[:, 1] += 4_000_000.0 + j * edge
            record = laspy.ScaleAwarePointRecord.zeros(len(pts), header=header)
            record.x, record.y, record.z = pts[:, 0], pts[:, 1], pts[:, 2]
            record.classification = cls.astype(np.uint8)
            writer.write_points(record)
    return side


def run(args: list[str]) -> tuple[float, float, str]:
    """(seconds, peak MB, stdout) of one ``lander detect`` process (its own peak resident
    memory, from wait4); its CPU seconds are printed too (a shared machine stretches the
    wall clock, not those)."""
    start = time.perf_counter()
    with tempfile.TemporaryFile("w+") as out, tempfile.TemporaryFile("w+") as err:
        child = subprocess.Popen(
            [sys.executable, "-c", "import sys; from autonomy.cli import main; "
             "sys.exit(main(sys.argv[1:]))", "detect", "--quiet", *args],
            stdout=out, stderr=err, env=os.environ,
        )
        _, status, usage = os.wait4(child.pid, 0)
        child.returncode = os.waitstatus_to_exitcode(status)
        seconds = time.perf_counter() - start
        out.seek(0)
        err.seek(0)
        if child.returncode != 0:
            raise SystemExit(f"lander detect failed: {err.read().strip()}")
        cpu = usage.ru_utime + usage.ru_stime
        print(f"    (lander detect {' '.join(args[:1] + args[2:])}: {seconds:.1f} s wall, "
              f"{cpu:.1f} s CPU)")
        return seconds, usage.ru_maxrss / 1024.0, out.read()


def sites(out: Path) -> list[tuple[str, ...]]:
    with open(out / "sites.csv") as f:
        return [(r["x"], r["y"], r["z"], r["size"]) for r in csv.DictReader(f)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--points", type=int, default=20_000_000)
    parser.add_argument("--small", type=int, default=2_000_000)
    a = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="bench-lidar-") as tmp:
        tmp = Path(tmp)
        small = tmp / "small.laz"
        t0 = time.perf_counter()
        side = write_scene(small, a.small, seed=1)
        print(f"small cloud: {a.small / 1e6:.1f} M points, {side:.0f} m square, written in "
              f"{time.perf_counter() - t0:.1f} s")
        tiled_s, tiled_mb, _ = run(["--lidar", str(small), "--tile-size", "200",
                                    "--out", str(tmp / "small_tiled")])
        # Read whole and searched as one tile (a 100 km tile holds it all).
        whole_s, whole_mb, _ = run(["--lidar", str(small), "--in-memory-points",
                                    str(a.small * 2), "--tile-size", "100000",
                                    "--out", str(tmp / "small_whole")])
        same = sites(tmp / "small_whole") == sites(tmp / "small_tiled")
        n = len(sites(tmp / "small_whole"))
        print(f"  whole cloud in memory: {whole_s:6.1f} s, peak {whole_mb:6.0f} MB")
        print(f"  streamed, 200 m tiles: {tiled_s:6.1f} s, peak {tiled_mb:6.0f} MB")
        print(f"  sites: {n}, identical whole vs tiled: {same}")
        big = tmp / "big.laz"
        t0 = time.perf_counter()
        side = write_scene(big, a.points, seed=2)
        print(f"big cloud: {a.points / 1e6:.1f} M points, {side:.0f} m square, "
              f"{big.stat().st_size / 1e6:.0f} MB LAZ, written in "
              f"{time.perf_counter() - t0:.1f} s")
        big_s, big_mb, out = run(["--lidar", str(big), "--tile-size", "200",
                                  "--out", str(tmp / "big")])
        print(f"  streamed, 200 m tiles: {big_s:6.1f} s ({a.points / big_s / 1e3:.0f} k "
              f"points/s), peak {big_mb:6.0f} MB")
        print("  " + next(line for line in out.splitlines() if "search points" in line))


if __name__ == "__main__":
    main()
