"""The LiDAR PCA and depth-costmap site sources in the perception loop (simulated sensors)."""

from __future__ import annotations

import numpy as np

from autonomy.perception.base import SiteSource
from autonomy.perception.costmap import DepthCostmapSource
from autonomy.perception.lidar import LidarPcaSource
from behaviors.ports import VehicleState
from lsd.depth_costmap.detector import DepthCostmapSettings
from lsd.lidar_pca.detector import LidarPcaSettings
from sitl.sensors import DepthCameraSettings
from sitl.sensors.lidar import LidarSettings
from sitl.terrain import is_safe, make_terrain


def state(x, y, z, yaw=0.0, agl=None):
    return VehicleState(position=(x, y, z), yaw=yaw, rangefinder_agl=agl, link_lost=False)


def test_lidar_source_accumulates_until_the_travel_distance_then_reports_safe_spots():
    terrain = make_terrain({"kind": "urban", "size": (160.0, 160.0)}, seed=4)
    source = LidarPcaSource.from_settings(
        terrain,
        rng=np.random.default_rng(0),
        lidar=LidarSettings(pattern="downward", channels=100, azimuth_steps=100,
                            vertical_fov_deg=70.0),
        detector=LidarPcaSettings(voxel_size=0.2, seeding="grid", grid_spacing=2.0,
                                  travel_distance=10.0, r_min=1.0, r_max=3.0,
                                  process_interval=None),
    )
    as_port: SiteSource = source  # the runner's port (structural)
    assert callable(as_port.update) and callable(as_port.drain_events)
    seen, first_at = [], None
    for i, x in enumerate(np.arange(-20.0, 8.0, 2.0)):
        obs = source.update(state(float(x), 0.0, 40.0), now=float(i))
        if obs and first_at is None:
            first_at = x
        seen += obs
    assert first_at is not None and first_at - (-20.0) >= 10.0  # nothing before 10 m of travel
    events = source.drain_events()
    assert events and all(e["event"] == "lidar_cloud_processed" for e in events)
    assert source.drain_events() == []
    xy = np.array([[o.x, o.y] for o in seen])
    # Spots are mostly on ground that the ground truth calls safe for a 1 m footprint.
    assert np.mean(is_safe(terrain, xy[:, 0], xy[:, 1])) >= 0.8
    best = source.best_spot(state(0.0, 0.0, 40.0))
    assert best is not None and best.source == "lidar_pca"
    counters = source.counters()
    assert counters["updates"] == 14 and counters["lidar_clouds_processed"] >= 2


def test_lidar_source_without_a_position_reports_nothing():
    terrain = make_terrain({"kind": "flat", "size": (40.0, 40.0)}, seed=0)
    source = LidarPcaSource.from_settings(terrain, rng=np.random.default_rng(0))
    assert source.update(VehicleState(), now=0.0) == []
    assert source.counters()["no_position"] == 1


def test_costmap_source_reports_clusters_on_flat_ground_and_counts_missing_frames():
    terrain = make_terrain({"kind": "flat", "size": (80.0, 80.0)}, seed=0)
    source = DepthCostmapSource.from_settings(
        terrain,
        rng=np.random.default_rng(0),
        camera=DepthCameraSettings(noise=False),
        detector=DepthCostmapSettings(vehicle_radius=0.5, cluster_dz=0.05),
    )
    as_port: SiteSource = source  # the runner's port (structural)
    assert callable(as_port.update) and callable(as_port.drain_events)
    assert source.update(VehicleState(), now=0.0) == []
    obs = source.update(state(0.0, 0.0, 10.0, agl=10.0), now=1.0)
    assert obs
    for o in obs:
        assert abs(o.z) < 0.05 and o.source == "depth_costmap"
        assert o.observation_altitude == np.float64(10.0 - o.z)
    assert any(e["event"] == "depth_source" for e in source.drain_events())
    counters = source.counters()
    assert counters["no_position"] == 1 and counters["costmap_frames"] == 1


def test_lidar_source_hovering_still_reports_spots_every_process_interval():
    terrain = make_terrain({"kind": "flat", "size": (60.0, 60.0)}, seed=0)
    source = LidarPcaSource.from_settings(
        terrain,
        rng=np.random.default_rng(0),
        lidar=LidarSettings(pattern="downward", channels=60, azimuth_steps=60,
                            vertical_fov_deg=90.0),
        detector=LidarPcaSettings(voxel_size=0.1, seeding="grid", grid_spacing=1.0,
                                  process_interval=2.0, r_min=0.5, r_max=1.5),
    )
    reports = [len(source.update(state(3.0, 3.0, 2.5), now=0.5 * i)) for i in range(9)]
    # Hovering at 2.5 m (no travel): clouds are processed at t = 2, 4 s, ... not before.
    assert reports[:4] == [0, 0, 0, 0] and reports[4] > 0
    spot = source.best_spot(state(3.0, 3.0, 2.5))
    assert spot.observation_altitude < 3.0  # seen from the verification altitude
