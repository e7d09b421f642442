"""Simulated LiDAR against known terrains, and the PCA detector on its scans."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from lsd.lidar_pca.detector import LidarPcaDetector, LidarPcaSettings
from sitl.sensors.lidar import LidarScanner, LidarSettings, beam_directions
from sitl.terrain import Terrain, make_terrain

DOWN = LidarSettings(pattern="downward", channels=40, azimuth_steps=40, vertical_fov_deg=60.0,
                     range_noise_std=0.0)


def flat(size=100.0, cell=0.5, z=0.0):
    n = int(size / cell) + 1
    return Terrain(np.full((n, n), z), cell, origin=(-size / 2, -size / 2))


def test_downward_scan_of_flat_ground_lies_on_the_ground_inside_the_fov():
    pts = LidarScanner(flat(), DOWN).scan([3.0, -2.0, 20.0], yaw=0.7)
    assert pts.shape == (40 * 40, 3)
    np.testing.assert_allclose(pts[:, 2], 0.0, atol=1e-6)
    reach = 20.0 * math.tan(math.radians(30.0)) * math.sqrt(2)
    assert np.hypot(pts[:, 0] - 3.0, pts[:, 1] + 2.0).max() <= reach + 1e-6


def test_range_noise_is_seeded_and_has_the_set_spread():
    s = DOWN.model_copy(update={"range_noise_std": 0.05})
    a = LidarScanner(flat(), s, rng=np.random.default_rng(1)).scan([0, 0, 20.0], 0.0)
    b = LidarScanner(flat(), s, rng=np.random.default_rng(1)).scan([0, 0, 20.0], 0.0)
    np.testing.assert_array_equal(a, b)
    # Range noise along near-vertical rays shows up in z with about the same spread.
    assert 0.03 < a[:, 2].std() < 0.07


def test_max_range_and_sky_give_no_points():
    spinning = LidarSettings(pattern="spinning", azimuth_steps=360, range_noise_std=0.0,
                             max_range=30.0)
    pts = LidarScanner(flat(), spinning).scan([0, 0, 20.0], 0.0)
    assert 0 < len(pts) < 16 * 360  # the upward half of the sweep hits nothing
    assert np.linalg.norm(pts - [0, 0, 20.0], axis=1).max() <= 30.0 + 1e-6
    assert len(LidarScanner(flat(), spinning).scan([0, 0, 40.0], 0.0)) == 0  # all beyond 30 m


def test_bad_pose_gives_an_empty_scan_and_is_counted():
    sc = LidarScanner(flat(), DOWN)
    assert sc.scan([0, np.nan, 20.0], 0.0).shape == (0, 3)
    assert sc.scan([0, 0, 20.0], float("inf")).shape == (0, 3)
    assert sc.skipped == 2


def test_beam_directions_are_unit_vectors():
    for s in (DOWN, LidarSettings()):
        d = beam_directions(s)
        np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0)
    with pytest.raises(ValidationError, match="max_range"):
        LidarSettings(min_range=10.0, max_range=5.0)


def test_detector_on_scans_of_an_urban_world_finds_flat_ground():
    terrain = make_terrain({"kind": "urban", "size": (120.0, 120.0)}, seed=2)
    scanner = LidarScanner(terrain, LidarSettings(pattern="downward", channels=120,
                                                  azimuth_steps=120, vertical_fov_deg=70.0),
                           rng=np.random.default_rng(0))
    det = LidarPcaDetector(LidarPcaSettings(voxel_size=0.2, seeding="grid", grid_spacing=2.0,
                                            travel_distance=10.0), rng=0)
    obs = []
    for x in np.arange(-10.0, 14.0, 2.0):
        pos = np.array([x, 0.0, 40.0])
        obs += det.add_scan(scanner.scan(pos, 0.0), pos, now=x)
    assert det.counters["clouds_processed"] >= 2 and obs
    for o in obs:  # spots lie on the terrain surface and below the slope limit
        assert o.z == pytest.approx(float(terrain.height(o.x, o.y)), abs=0.3)
    assert np.degrees(det.spots.slope).max() <= 15.0
