"""A few perception frames of the Mars mission, bit for bit: the depth camera's images over
the seed-0 world from cruise altitude, from the stereo band and from the verification
height, each fused into the elevation map and analysed. ``python tests/speed/frames.py
--write`` records their digests into tests/speed/data/golden_frames.json."""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import sys
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data" / "golden_frames.json"

# (x, y, z, yaw, time) of the camera: a cruise leg at 100 m (SfM needs lateral motion),
# a descent through the stereo band and a hover over one spot.
POSES = [
    (20.0, -60.0, 100.0, 0.0, 10.0),
    (40.0, -60.0, 100.0, 0.0, 11.0),
    (60.0, -59.0, 100.0, 0.1, 12.0),
    (100.0, 40.0, 30.0, 1.2, 40.0),
    (101.0, 40.5, 12.0, 1.3, 44.0),
    (101.5, 40.5, 6.0, 1.3, 46.0),
    (101.6, 40.4, 4.0, 1.3, 47.0),
    (101.6, 40.4, 4.0, 1.3, 47.25),
]


def _sha(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()


def frame_digests() -> list[dict[str, Any]]:
    """Digests of every frame's depth and sigma, the maps after fusing it, and the sites
    the detector reports."""
    from autonomy.config import load_mission
    from autonomy.perception.camera import to_depth_frame
    from autonomy.perception.elevation import ElevationMapSource
    from autonomy.runner.world import FlightSeeds, build_terrain

    mission = load_mission(ROOT / "missions" / "mars_science.yaml")
    seeds = FlightSeeds.derive(0)
    terrain = build_terrain(mission, seeds.terrain)
    p = mission.perception
    source = ElevationMapSource.from_settings(
        terrain, rng=np.random.default_rng(seeds.perception), camera=p.camera,
        rangefinder=p.rangefinder, elevation_map=p.elevation_map, detector=p.detection,
    )
    out = []
    for x, y, z, yaw, t in POSES:
        rendered = source.camera.render(np.array([x, y, z]), yaw, t)
        if rendered is None:
            out.append({"t": t, "frame": None})
            continue
        sites = source.detect(to_depth_frame(rendered))
        detector = source.detector
        grid = detector.fine_map if detector.low else detector.map
        out.append({
            "t": t,
            "depth": _sha(rendered.depth),
            "sigma": _sha(rendered.sigma),
            "map": [_sha(a) for a in (grid.mean, grid.variance, grid.top, grid.closest)],
            "sites": json.loads(json.dumps([dataclasses.asdict(s) for s in sites])),
        })
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true")
    args = parser.parse_args(argv)
    got = frame_digests()
    if args.write:
        DATA.write_text(json.dumps(got, indent=1) + "\n")
        from golden import write_libraries  # this script runs from its folder

        write_libraries()
        print(f"recorded {len(got)} frames in {DATA}")
        return 0
    same = json.dumps(got) == json.dumps(json.loads(DATA.read_text()))
    print("same" if same else "DIFFERENT")
    return 0 if same else 1


if __name__ == "__main__":
    # As a script: this checkout's packages ahead of the environment's editable install
    # (which may point at another checkout), unless the caller chose them by PYTHONPATH.
    if not os.environ.get("PYTHONPATH"):
        sys.path.insert(0, str(ROOT))
    sys.exit(main())
