"""The runner builds the site source the mission names, over the mission's world."""

from __future__ import annotations

import numpy as np
import pytest

from autonomy.config import Mission
from autonomy.runner.world import build_source, build_terrain
from behaviors.ports import VehicleState


@pytest.mark.parametrize(("detector", "source_class"), [
    ("elevation_map", "ElevationMapSource"),
    ("depth_costmap", "DepthCostmapSource"),
    ("lidar_pca", "LidarPcaSource"),
    ("scripted", "ScriptedSiteSource"),
])
def test_each_detector_is_built_and_fed_from_vehicle_states(detector, source_class):
    mission = Mission(
        waypoints=[(20.0, 0.0, 10.0)],
        world={"kind": "flat", "size": [60.0, 60.0], "cell_size": 0.5},
        perception={"detector": detector, "camera": {"width": 128, "height": 128,
                                                     "focal_px": 128.0}},
        sites=[{"x": 1.0, "y": 2.0}],
    )
    terrain = build_terrain(mission, seed=0)
    source = build_source(mission, terrain, np.random.default_rng(0))
    assert type(source).__name__ == source_class
    seen = []
    # Fly east at 25 m above the ground at 5 m/s, one update per second: structure from
    # motion has a baseline of several metres.
    for t in range(10):
        state = VehicleState(time=float(t), position=(5.0 * t - 20.0, 0.0, 25.0),
                             rangefinder_agl=25.0)
        seen += source.update(state, float(t))
    assert source.counters()["updates" if detector != "scripted" else "observations"] >= 1
    if detector == "depth_costmap":
        return  # its costmaps find nothing on a featureless plane (min-max normalised)
    assert seen, f"{detector}: no site over flat ground"
    assert all(0.0 <= o.roughness <= 1.0 and o.size >= 0 for o in seen)
    assert np.median([abs(o.z) for o in seen]) < 1.0  # on the ground
    assert isinstance(source.drain_events(), list)
