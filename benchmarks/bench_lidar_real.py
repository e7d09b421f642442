"""How safe are the LiDAR detector's sites? Each cloud's sites are judged against the
cloud's own ASPRS labels and a least-squares plane fit (lsd.lidar_pca.judge: disc and 1 m
clearance ring of ground only, slope <= 15 deg, RMS residual <= 5 cm, no step over 15 cm,
nothing over 0.5 m in the ring), beside random discs of r_min on the same cloud.

Clouds: the real classified tiles in tests/data/real (see the README there) and synthetic
classified scenes (urban, farmland, forest: lsd.lidar_pca.scenes). Rows:

- ``detector``: the defaults of ``lander detect`` (grid seeding, class rules, site rules);
- ``no classes``: the same without the file's classification (geometry alone);
- ``no max_gap``, ``no classes, no max_gap``: those two without the coverage rule (a disc or
  clearance ring partly without returns, as at the edge of the data, was taken as clear);
- ``before``: the settings before issue 16 (no class rules, no residual or ring checks,
  max_step 0.3 m, overlapping sites), for comparison;
- ``random``: 500 random discs of r_min (1.5 m).

    python benchmarks/bench_lidar_real.py
"""

from __future__ import annotations

import time
from collections import Counter
from pathlib import Path

import _checkout  # noqa: F401  (this checkout's packages first)
import numpy as np

from lsd.io import read_point_cloud
from lsd.lidar_pca.detector import detect_planes, spot_grades
from lsd.lidar_pca.judge import Judge, JudgeRules, random_discs
from lsd.lidar_pca.scenes import scene
from lsd.lidar_pca.settings import LidarPcaSettings
from lsd.lidar_pca.sites import find_sites, finish_sites
from lsd.pointcloud import thin_by_distance, voxel_grid

REAL = Path(__file__).resolve().parents[1] / "tests" / "data" / "real"
DEFAULTS = LidarPcaSettings(seeding="grid")
NO_GAP_RULE = DEFAULTS.model_copy(update={"max_gap": None})
BEFORE = DEFAULTS.model_copy(update={
    "residual_max": None, "max_step": 0.3, "obstacle_height": None, "merge_distance": 1.0,
    "classes": DEFAULTS.classes.model_copy(update={"enabled": False}),
})


def clouds():
    for path in sorted(REAL.glob("*.la[sz]")):
        data = read_point_cloud(path)
        yield path.stem, data.points, data.classification
    for kind in ("urban", "farmland", "forest"):
        points, codes = scene(kind, size=100.0, seed=11)
        yield f"synthetic {kind} 100 m", points, codes


def sites(points, codes, settings):
    """The sites ``lander detect`` reports with ``settings``."""
    spots, counts = find_sites(points, codes, settings, np.random.default_rng(0))
    return finish_sites(spots, settings, counts)


def sites_before(points, settings):
    """What the detector reported before issue 16: every accepted plane, spots closer
    than merge_distance merged (the better stays), overlapping discs kept."""
    grid = voxel_grid(points, settings.voxel_size)
    spots = detect_planes(grid, settings, np.random.default_rng(0)).spots
    ranked = spots.take(np.argsort(-spot_grades(spots, settings), kind="stable"))
    return ranked.take(thin_by_distance(ranked.centre, settings.merge_distance))


def line(name, safe, why=()):
    if len(safe) == 0:
        return f"  {name:24s}     0 sites"
    gaps = Counter(w for w in why if w.endswith("not covered"))
    said = "; " + ", ".join(f"{k} {v}" for k, v in sorted(gaps.items())) if gaps else ""
    return f"  {name:24s} {len(safe):5d} sites  {100 * safe.mean():5.1f}% safe{said}"


def main() -> None:
    rules = JudgeRules.from_settings(DEFAULTS)
    print("sites judged safe (labels + plane fit), per cloud")
    for name, points, codes in clouds():
        start = time.perf_counter()
        judge = Judge(points, codes, rules)
        labelled = "classified" if judge.codes is not None else "no ground class"
        print(f"{name}: {len(points):,} points ({labelled})")
        runs = (("detector", sites(points, codes, DEFAULTS)),
                ("no max_gap", sites(points, codes, NO_GAP_RULE)),
                ("no classes", sites(points, None, DEFAULTS)),
                ("no classes, no max_gap", sites(points, None, NO_GAP_RULE)),
                ("before", sites_before(points, BEFORE)))
        for label, spots in runs:
            print(line(label, *judge.judge(spots.centre[:, :2], spots.radius)))
        centres = random_discs(points, 500, DEFAULTS.r_min, np.random.default_rng(1))
        safe, _ = judge.judge(centres, DEFAULTS.r_min)
        print(line("random", safe) + f"   ({time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main()
