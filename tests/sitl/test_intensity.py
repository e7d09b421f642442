"""The textured camera: each world's albedo map and the greyscale frames rendered from the
depth camera's ray casting."""

from __future__ import annotations

import functools

import cv2
import numpy as np
import pytest

from sitl.sensors import DepthCamera, DepthCameraSettings, RenderedDepth, nadir_rotation
from sitl.sensors.intensity import IntensityCameraSettings, hit_points, render_intensity
from sitl.terrain import Terrain, make_terrain
from sitl.terrain.albedo import AlbedoMap, Sun

FAR = 10_000.0
CAMERA = DepthCameraSettings(width=320, height=240, focal_px=160.0, noise=False,
                             stereo_below=FAR, sfm_above=FAR, stereo_max_range=FAR)


@functools.lru_cache(maxsize=4)
def _world(kind: str):
    settings = {"kind": kind, "size": [120.0, 120.0], "cell_size": 0.25}
    terrain = make_terrain(settings, seed=3)
    return terrain, AlbedoMap(terrain, np.random.default_rng(5))


def _frame(terrain, albedo, x, y, height, seed=0, **settings):
    camera = DepthCamera(terrain, CAMERA, rng=np.random.default_rng(0))
    rendered = camera.render((x, y, float(terrain.height(x, y)) + height), 0.4, 0.0, agl=0.0)
    return render_intensity(rendered, albedo, np.random.default_rng(seed),
                            IntensityCameraSettings(**settings))


def test_urban_features_get_their_own_albedo():
    terrain, albedo = _world("urban")
    grid = terrain.grid
    floor = np.percentile(grid, 0.5)
    road = grid - floor < 0.05
    pavement = np.abs(grid - floor - 0.15) < 0.01
    roofs = grid - floor > 3.0
    assert road.any() and pavement.any() and roofs.any()
    # Asphalt is darker than pavement and grass, roofs differ from building to building.
    assert np.median(albedo.albedo[road]) < np.median(albedo.albedo[pavement])
    assert np.unique(np.round(albedo.albedo[roofs], 3)).size > 3


def test_mars_rocks_are_darker_than_the_regolith_around_them():
    terrain, albedo = _world("mars")
    ground = terrain.grid - cv2.blur(terrain.grid, (21, 21))
    rocks = ground > 0.3
    assert rocks.sum() > 10
    assert np.median(albedo.albedo[rocks]) < np.median(albedo.albedo[np.abs(ground) < 0.02])


def test_the_sunlit_side_of_a_ridge_is_brighter():
    x = np.arange(81) * 0.25
    ridge = np.tile(np.maximum(0, 5.0 - np.abs(x - 10.0)), (81, 1)).astype(np.float32)
    terrain = Terrain(ridge, 0.25, (0.0, 0.0), kind="flat")
    east_sun = AlbedoMap(terrain, np.random.default_rng(0), Sun(azimuth=90.0, elevation=30.0))
    west_face = east_sun.shading[:, 25:35].mean()  # slope facing west (x < 10)
    east_face = east_sun.shading[:, 45:55].mean()
    assert east_face > west_face + 0.3


@pytest.mark.parametrize("kind", ["mars", "urban"])
@pytest.mark.parametrize("height", [20.0, 3.0])
def test_frames_have_corners_to_track_from_high_and_low(kind, height):
    terrain, albedo = _world(kind)
    frame = _frame(terrain, albedo, 30.0, 20.0, height)
    assert frame.dtype == np.uint8 and frame.shape == (240, 320)
    assert 20 < frame.mean() < 230 and frame.std() > 5  # exposed, not washed out
    corners = cv2.goodFeaturesToTrack(frame, 1000, 0.01, 5)
    assert corners is not None and len(corners) > 300


def test_pixels_show_the_albedo_where_their_rays_hit_the_ground():
    terrain = Terrain(np.zeros((201, 201), np.float32), 0.25, (-25.0, -25.0), kind="flat")
    albedo = AlbedoMap(terrain, np.random.default_rng(1))
    camera = DepthCamera(terrain, CAMERA)
    yaw, height = 0.7, 6.0
    rendered = camera.render((1.0, -2.0, height), yaw, 0.0, agl=0.0)
    x, y, z = hit_points(rendered)
    # A pinhole over level ground: pixel (u, v) sees (u - cx, v - cy) * h / f along the
    # camera's right and down axes.
    u, v = np.meshgrid(np.arange(320) - rendered.cx, np.arange(240) - rendered.cy)
    right = np.array([np.sin(yaw), -np.cos(yaw)])
    down = -np.array([np.cos(yaw), np.sin(yaw)])
    ex = 1.0 + (u * right[0] + v * down[0]) * height / 160.0
    ey = -2.0 + (u * right[1] + v * down[1]) * height / 160.0
    assert np.abs(x - ex).max() < 1e-3 and np.abs(y - ey).max() < 1e-3 and np.abs(z).max() < 1e-3
    frame = render_intensity(rendered, albedo, np.random.default_rng(0),
                             IntensityCameraSettings(noise_std=0.0, gain=300.0))
    expected = 300.0 * albedo.radiance(ex, ey, np.zeros_like(ex), height / 160.0)
    assert np.abs(frame - np.clip(np.rint(expected), 0, 255)).max() <= 1


def test_no_return_is_black_and_noise_comes_from_the_generator_given():
    terrain, albedo = _world("urban")
    depth = np.full((24, 32), 5.0, np.float32)
    depth[:, :8] = np.nan
    rendered = RenderedDepth(depth=depth, sigma=depth * 0, fx=16.0, fy=16.0, cx=15.5, cy=11.5,
                             width=32, height=24, position=np.array([0.0, 0.0, 5.0]),
                             rotation=nadir_rotation(0.0), timestamp=0.0, source="stereo")
    a = render_intensity(rendered, albedo, np.random.default_rng(9))
    b = render_intensity(rendered, albedo, np.random.default_rng(9))
    c = render_intensity(rendered, albedo, np.random.default_rng(10))
    assert (a[:, :8] == 0).all() and (a[:, 8:] > 0).any()
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_the_same_generator_gives_the_same_world():
    terrain, _ = _world("mars")
    a = AlbedoMap(terrain, np.random.default_rng(2))
    b = AlbedoMap(terrain, np.random.default_rng(2))
    assert np.array_equal(a.albedo, b.albedo)
    points = np.array([1.234, 7.5]), np.array([-3.0, 4.25]), np.zeros(2), np.full(2, 0.02)
    assert np.array_equal(a.radiance(*points), b.radiance(*points))
