"""Simulated depth camera and range finder over constructed terrains."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from sitl.sensors import (
    DepthCamera,
    DepthCameraSettings,
    RangeFinder,
    RangeFinderSettings,
    depth_sigma,
    nadir_rotation,
)
from sitl.sensors.raycast import HeightBounds, cast_pinhole_rays, cast_rays, coarse_terrain
from sitl.terrain import Terrain, make_terrain

CELL = 0.2
AXIS = np.arange(-160.0, 160.0 + CELL / 2, CELL)
X, Y = np.meshgrid(AXIS, AXIS)
EXACT_RANGE = RangeFinderSettings(noise_std=0.0, max_range=200.0)


def terrain_of(heights: np.ndarray) -> Terrain:
    return Terrain(heights, CELL, origin=(AXIS[0], AXIS[0]))


def camera(terrain: Terrain, seed: int = 0, **settings) -> DepthCamera:
    rng = np.random.default_rng(seed)
    return DepthCamera(
        terrain,
        DepthCameraSettings(**settings),
        rangefinder=RangeFinder(terrain, EXACT_RANGE, rng=rng),
        rng=rng,
    )


def analytic_plane_depth(frame, a: float, b: float, c: float) -> np.ndarray:
    """Depth along the optical axis of the plane z = a x + b y + c for every pixel."""
    v, u = np.mgrid[0 : frame.height, 0 : frame.width]
    rays = (
        np.stack(((u - frame.cx) / frame.fx, (v - frame.cy) / frame.fy, np.ones(u.shape)), axis=-1)
        @ np.asarray(frame.rotation).T
    )
    px, py, pz = frame.position
    return (a * px + b * py + c - pz) / (rays[..., 2] - a * rays[..., 0] - b * rays[..., 1])


def fly_sideways(cam: DepthCamera, start, distance: float, yaw: float = 0.0, duration=1.0):
    """Feed poses moving ``distance`` metres east over ``duration`` seconds; returns the
    end position and time."""
    start = np.asarray(start, dtype=float)
    for k in range(11):
        cam.observe_pose(start + [distance * k / 10, 0.0, 0.0], yaw, duration * k / 10)
    return start + [distance, 0.0, 0.0], duration


def test_nadir_rotation_looks_down_with_image_up_forward():
    rot = nadir_rotation(np.pi / 2)  # heading north
    np.testing.assert_allclose(rot @ [0, 0, 1], [0, 0, -1], atol=1e-12)  # optical axis down
    np.testing.assert_allclose(rot @ [0, -1, 0], [0, 1, 0], atol=1e-12)  # image up = north
    np.testing.assert_allclose(rot @ [1, 0, 0], [1, 0, 0], atol=1e-12)  # right = east
    np.testing.assert_allclose(rot.T @ rot, np.eye(3), atol=1e-12)
    assert np.linalg.det(rot) == pytest.approx(1.0)


@pytest.mark.parametrize("altitude, yaw", [(12.0, 0.4), (100.0, -2.0)])
def test_depth_over_a_tilted_plane_matches_the_analytic_depth(altitude, yaw):
    a, b, c = 0.15, -0.25, 3.0
    cam = camera(terrain_of(a * X + b * Y + c), noise=False)
    start = [-20.0, 10.0, altitude + a * -20.0 + b * 10.0 + c]
    end, now = fly_sideways(cam, start, 15.0, yaw)
    frame = cam.render(end, yaw, now)
    assert frame is not None and frame.depth.shape == (256, 256)
    assert frame.source == ("stereo" if altitude < 15 else "sfm")
    expected = analytic_plane_depth(frame, a, b, c)
    assert np.all(np.isfinite(frame.depth))
    np.testing.assert_allclose(frame.depth, expected, atol=2e-3 * altitude)


def test_depth_error_model_gives_1_3_m_at_100_m_with_15_m_baseline():
    assert depth_sigma(100.0, 256.0, 15.0, 0.5) == pytest.approx(1.302, abs=1e-3)
    cam = camera(terrain_of(np.zeros_like(X)))
    end, now = fly_sideways(cam, [-20.0, 0.0, 100.0], 20.0)  # capped at the 15 m keyframe
    frame = cam.render(end, 0.0, now)
    assert frame.source == "sfm" and frame.baseline == pytest.approx(15.0)
    centre = frame.sigma[127:129, 127:129]
    np.testing.assert_allclose(centre, 1.302, atol=0.01)
    # a level plane is at the same depth along the optical axis in every pixel
    assert np.allclose(frame.sigma, frame.sigma[128, 128], rtol=1e-3)


def test_noise_follows_the_per_pixel_sigma_and_is_seeded():
    terrain = terrain_of(np.zeros_like(X))
    frames = []
    for seed in (7, 7, 8):
        cam = camera(terrain, seed=seed)
        end, now = fly_sideways(cam, [-20.0, 0.0, 60.0], 10.0)
        frames.append(cam.render(end, 0.0, now))
    a, b, c = frames
    np.testing.assert_array_equal(a.depth, b.depth)
    assert not np.array_equal(a.depth, c.depth)
    z = (a.depth - 60.0) / a.sigma
    assert abs(float(np.mean(z))) < 0.05
    assert float(np.std(z)) == pytest.approx(1.0, abs=0.05)


def test_no_sfm_depth_when_only_climbing_or_hovering():
    cam = camera(terrain_of(np.zeros_like(X)))
    frames = [cam.render([5.0, 5.0, 40.0 + 2.0 * k], 0.3, 0.5 * k) for k in range(10)]
    assert all(f is None for f in frames)
    assert cam.source == "sfm"
    assert cam.skipped["sfm_baseline"] == 10
    events = cam.drain_events()
    assert events[0] == {"event": "depth_source", "source": "sfm", "agl": 40.0}
    skips = [e for e in events if e["event"] == "depth_skipped"]
    assert len(skips) == 1 and skips[0]["reason"] == "sfm_baseline"
    # moving sideways brings the depth back
    for k in range(5):
        cam.observe_pose([5.0 + 2.0 * k, 5.0, 60.0], 0.3, 10.0 + 0.25 * k)
    assert cam.render([13.0, 5.0, 60.0], 0.3, 11.0) is not None


def test_stereo_gives_depth_without_motion_at_low_altitude():
    cam = camera(terrain_of(np.zeros_like(X)))
    frame = cam.render([0.0, 0.0, 2.5], 0.0, 0.0)
    assert frame is not None and frame.source == "stereo"
    assert frame.baseline == pytest.approx(0.2)
    expected_sigma = 2.5**2 / (256 * 0.2) * 0.5
    np.testing.assert_allclose(frame.sigma, expected_sigma, rtol=1e-3)


def test_stereo_range_is_limited():
    cam = camera(terrain_of(np.zeros_like(X)), stereo_max_range=12.0, noise=False)
    frame = cam.render([0.0, 0.0, 11.0], 0.0, 0.0)
    # the axis sees 11 m; the image corners' depth is 11 m too on a level plane
    assert np.all(np.isfinite(frame.depth))
    cam = camera(terrain_of(np.zeros_like(X)), stereo_max_range=10.0, noise=False)
    assert np.all(np.isnan(cam.render([0.0, 0.0, 11.0], 0.0, 0.0).depth))


def test_source_switches_on_range_finder_agl_with_hysteresis():
    terrain = terrain_of(np.zeros_like(X))
    cam = camera(terrain)
    altitudes = [30.0, 18.0, 16.0, 14.0, 17.0, 19.5, 21.0, 16.0, 14.5]
    sources = []
    for k, z in enumerate(altitudes):
        # lateral motion so that SfM frames exist
        cam.render([3.0 * k, 0.0, z], 0.0, 0.5 * k)
        sources.append(cam.source)
    assert sources == ["sfm", "sfm", "sfm", "stereo", "stereo", "stereo", "sfm", "sfm", "stereo"]
    switches = [e for e in cam.drain_events() if e["event"] == "depth_source"]
    assert [(e["source"], e["agl"]) for e in switches] == [
        ("sfm", 30.0),
        ("stereo", 14.0),
        ("sfm", 21.0),
        ("stereo", 14.5),
    ]


def test_beyond_the_range_finder_range_counts_as_high():
    terrain = terrain_of(np.zeros_like(X))
    cam = DepthCamera(terrain, rangefinder=RangeFinder(terrain, RangeFinderSettings()))
    cam.render([0.0, 0.0, 90.0], 0.0, 0.0)  # default range finder: 40 m
    assert cam.source == "sfm"
    assert cam.drain_events()[0]["agl"] is None


def test_range_finder_measures_agl_over_a_raised_box():
    box = (np.abs(X - 10.0) <= 3.0) & (np.abs(Y) <= 3.0)
    terrain = terrain_of(np.where(box, 2.0, 0.0))
    finder = RangeFinder(terrain, RangeFinderSettings(noise_std=0.0, max_range=40.0))
    assert finder.measure([10.0, 0.0, 10.0]) == pytest.approx(8.0)
    assert finder.measure([-10.0, 0.0, 10.0]) == pytest.approx(10.0)
    assert finder.measure([10.0, 0.0, 50.0]) is None  # beyond max range
    assert finder.measure([10.0, 0.0, 2.1]) is None  # below min range
    assert finder.measure([np.nan, 0.0, 10.0]) is None
    noisy = RangeFinder(terrain, RangeFinderSettings(noise_std=0.05), np.random.default_rng(1))
    readings = np.array([noisy.measure([10.0, 0.0, 10.0]) for _ in range(400)])
    assert readings.mean() == pytest.approx(8.0, abs=0.01)
    assert readings.std() == pytest.approx(0.05, rel=0.2)


def test_depth_sees_a_raised_box():
    box = (np.abs(X - 1.0) <= 2.0) & (np.abs(Y) <= 2.0)
    cam = camera(terrain_of(np.where(box, 3.0, 0.0)), noise=False)
    frame = cam.render([0.0, 0.0, 10.0], 0.0, 0.0)
    assert frame.depth[128, 128] == pytest.approx(7.0, abs=1e-3)  # box top under the camera
    assert np.nanmax(frame.depth) == pytest.approx(10.0, abs=1e-3)  # ground beside it


@pytest.mark.parametrize(
    "pose",
    [([np.nan, 0.0, 50.0], 0.0, 1.0), ([0.0, 0.0, 50.0], np.inf, 1.0), ([0.0, 0.0], 0.0, 1.0)],
)
def test_invalid_pose_skips_the_frame_with_an_event(pose):
    cam = camera(terrain_of(np.zeros_like(X)))
    assert cam.render(*pose) is None
    assert cam.skipped["invalid_pose"] == 1
    assert cam.drain_events() == [{"event": "depth_skipped", "reason": "invalid_pose"}]
    assert cam.drain_events() == []


def test_camera_under_the_ground_is_skipped():
    cam = camera(terrain_of(np.full_like(X, 5.0)))
    assert cam.render([0.0, 0.0, 3.0], 0.0, 0.0) is None
    assert cam.skipped["camera_below_ground"] == 1


def test_rendering_a_generated_world_lands_on_its_surface():
    terrain = make_terrain({"kind": "urban", "size": (160.0, 160.0)}, seed=2)
    # full resolution: at 80 m the default renders the pixel footprint's mean heights
    cam = camera(terrain, noise=False, level_of_detail=False)
    end, now = fly_sideways(cam, [-30.0, -20.0, 80.0], 15.0, yaw=0.7)
    frame = cam.render(end, 0.7, now)
    v, u = np.mgrid[0:256, 0:256]
    cam_pts = (
        np.stack(((u - frame.cx) / frame.fx, (v - frame.cy) / frame.fy, np.ones(u.shape)), axis=-1)
        * frame.depth[..., None]
    )
    world = cam_pts @ frame.rotation.T + frame.position
    gap = world[..., 2] - terrain.height(world[..., 0], world[..., 1])
    # rays meeting a wall head-on may land within a cell of its foot; nearly all are exact
    assert np.mean(np.abs(gap) < 0.01) > 0.99


def test_bad_sensor_settings_name_the_field():
    with pytest.raises(ValidationError, match="sfm_above"):
        DepthCameraSettings(stereo_below=20.0, sfm_above=15.0)
    with pytest.raises(ValidationError, match="max_range"):
        RangeFinderSettings(min_range=5.0, max_range=1.0)
    with pytest.raises(ValidationError, match="width"):
        DepthCameraSettings(width=0)


def test_rendered_depth_converts_to_a_detector_frame_on_the_terrain():
    from autonomy.perception.camera import to_depth_frame

    slope = terrain_of(0.1 * X)
    cam = camera(slope, noise=False)
    rendered = cam.render([4.0, -3.0, 9.0], 1.1, 2.5)
    frame = to_depth_frame(rendered)
    assert frame.source == "stereo" and frame.timestamp == 2.5
    assert frame.intrinsics.width == 256 and frame.intrinsics.fx == 256.0
    points, sigma = frame.to_points()
    assert points.shape == (256 * 256, 3) and sigma.shape == (256 * 256,)
    np.testing.assert_allclose(points[:, 2], 0.1 * points[:, 0], atol=2e-3)


def test_image_up_is_the_vehicle_heading():
    box = (np.abs(X) <= 2.1) & (np.abs(Y - 6.0) <= 2.1)  # 6 m north of the vehicle
    cam = camera(terrain_of(np.where(box, 4.0, 0.0)), noise=False)
    frame = cam.render([0.0, 0.0, 12.0], np.pi / 2, 0.0)  # heading north
    rows, cols = np.nonzero(frame.depth < 10.0)
    assert rows.size and rows.max() < frame.cy  # in the upper half
    assert abs(cols.mean() - frame.cx) < 2.0
    frame = cam.render([0.0, 0.0, 12.0], 0.0, 1.0)  # heading east: north is to the left
    rows, cols = np.nonzero(frame.depth < 10.0)
    assert cols.max() < frame.cx and abs(rows.mean() - frame.cy) < 2.0


def test_beyond_the_terrain_edge_the_ground_continues():
    cam = camera(terrain_of(np.zeros_like(X)), noise=False)
    frame = cam.render([400.0, -300.0, 20.0], 0.0, 0.0)
    np.testing.assert_allclose(frame.depth, 20.0, atol=1e-3)


def fine_reference_depth(terrain: Terrain, frame) -> np.ndarray:
    """The exact (slow) answer: every pixel's ray marched an eighth of a cell at a time,
    bisected and interpolated on the exact bilinear surface."""
    v, u = np.mgrid[0 : frame.height, 0 : frame.width]
    rays = (
        np.stack(((u - frame.cx) / frame.fx, (v - frame.cy) / frame.fy, np.ones(u.shape)), axis=-1)
        @ np.asarray(frame.rotation).T
    )
    t = cast_rays(terrain, frame.position, rays.reshape(-1, 3), step=terrain.cell_size / 8)
    return t.reshape(frame.height, frame.width)


@pytest.mark.parametrize("agl, seed", [(40.0, 1), (12.0, 2), (3.0, 3)])
def test_depth_over_rocky_mars_matches_a_fine_step_reference(agl, seed):
    settings = {"kind": "mars", "size": (120.0, 120.0), "rock_field_fraction": 1.0}
    terrain = make_terrain({**settings, "rock_density": 0.5}, seed=seed)
    rng = np.random.default_rng(seed)
    # full resolution at every altitude (the level of detail has its own test below)
    cam = camera(terrain, noise=False, width=128, height=128, focal_px=128.0, level_of_detail=False)
    x, y = rng.uniform(-30.0, 30.0, 2)
    z = float(terrain.height(x, y)) + agl
    end, now = fly_sideways(cam, [x - 15.0, y, z], 15.0, yaw=0.3)
    frame = cam.render(end, 0.3, now)
    exact = fine_reference_depth(terrain, frame)
    err = np.abs(frame.depth - exact)
    assert np.all(np.isfinite(frame.depth))
    # Heights come from fixed-point bilinear weights (1/32 cell) and the refinement stops
    # within 0.5 mm of the ground: 2 cm holds everywhere but at a few grazing rays whose
    # first hit a one-cell march step and an eighth-cell one see differently.
    assert np.mean(err < 0.02) >= 0.995
    assert np.median(err) < 2e-3


@pytest.mark.parametrize("agl, seed", [(100.0, 1), (60.0, 2), (40.0, 3)])
def test_at_altitude_depth_stays_within_a_fifth_of_its_noise_of_the_full_terrain(agl, seed):
    # At 40-100 m the 128 px / f = 128 px camera's pixel covers 0.3-0.8 m: the default
    # renders the mean heights of 0.4 m cells. Against the full-resolution depth it is
    # off by less than a fifth of the depth noise sigma (the best case: the 15 m SfM
    # keyframe baseline) on 99% of the pixels, a centimetre at the median; only rock and
    # crater edges, smoothed over a pixel, differ more.
    settings = {"kind": "mars", "size": (160.0, 160.0), "rock_field_fraction": 1.0}
    terrain = make_terrain({**settings, "rock_density": 0.5}, seed=seed)
    rng = np.random.default_rng(seed)
    cam = camera(terrain, noise=False, width=128, height=128, focal_px=128.0)
    x, y = rng.uniform(-30.0, 30.0, 2)
    z = float(terrain.height(x, y)) + agl
    end, now = fly_sideways(cam, [x - 15.0, y, z], 15.0, yaw=0.3)
    frame = cam.render(end, 0.3, now)
    assert frame.baseline == pytest.approx(15.0)
    err = np.abs(frame.depth - fine_reference_depth(terrain, frame))
    assert np.mean(err < 0.2 * frame.sigma) >= 0.99
    assert np.median(err) < 0.01
    # ... and it is the level of detail that differs: the full-resolution frame is exact
    full = camera(
        terrain, noise=False, width=128, height=128, focal_px=128.0, level_of_detail=False
    )
    fly_sideways(full, [x - 15.0, y, z], 15.0, yaw=0.3)
    assert np.median(np.abs(full.render(end, 0.3, now).depth - frame.depth)) > 1e-3


def test_at_low_altitude_the_full_terrain_is_rendered():
    # 12 m: a 256 px / f = 256 px pixel covers 5 cm, finer than the 0.2 m cells
    terrain = make_terrain({"kind": "mars", "size": (60.0, 60.0), "rock_density": 0.5}, seed=5)
    z = float(terrain.height(3.0, 2.0)) + 12.0
    default = camera(terrain, noise=False).render([3.0, 2.0, z], 0.5, 0.0)
    full = camera(terrain, noise=False, level_of_detail=False).render([3.0, 2.0, z], 0.5, 0.0)
    np.testing.assert_array_equal(default.depth, full.depth)


def test_a_ray_passing_beside_a_wall_top_hits_its_side_first():
    # A 6 m wall, one cell thick at x = 2 m; the camera 10 m up at x = 0 sees past its top
    # onto its face: those rays must stop at the wall, not at the ground behind it.
    wall = np.abs(X - 2.0) < CELL / 2
    terrain = terrain_of(np.where(wall, 6.0, 0.0))
    cam = camera(terrain, noise=False)
    frame = cam.render([0.0, 0.0, 10.0], np.pi / 2, 0.0)  # heading north: right = east
    row = frame.depth[128]
    ground_x = (np.arange(256) - frame.cx) / frame.fx * 10.0  # where the ground would be
    hit_x = (np.arange(256) - frame.cx) / frame.fx * row
    # rays that would reach the ground behind the wall but pass under its top (by 1 m or
    # more: a ray grazing the top meets the one-cell-wide ridge over less than the eighth
    # of a cell the renderer looks at)
    shadowed = (ground_x > 2.2) & (ground_x < 4.0)
    assert shadowed.sum() > 40
    assert np.all(row[shadowed] < 10.0 - 1e-3)
    # ... on the face's bilinear ramp between x = 1.8 m and 2.2 m
    assert np.all((hit_x[shadowed] > 1.8 - 1e-6) & (hit_x[shadowed] <= 2.2 + 1e-6))
    exact = fine_reference_depth(terrain, frame)[128]
    np.testing.assert_allclose(row[shadowed], exact[shadowed], atol=0.02)


def test_height_bounds_hold_the_surface_of_every_box():
    terrain = make_terrain({"kind": "rubble", "size": (60.0, 60.0)}, seed=4)
    bounds = HeightBounds(terrain)
    rng = np.random.default_rng(4)
    (xmin, xmax, ymin, ymax), cs = terrain.extent, terrain.cell_size
    x0, y0 = rng.uniform(xmin - 5.0, xmax, 200), rng.uniform(ymin - 5.0, ymax, 200)
    w, h = rng.exponential(2.0, 200), rng.exponential(2.0, 200)
    ox, oy = terrain.origin
    high, low = bounds.region(
        (x0 - ox) / cs, (x0 + w - ox) / cs, (y0 - oy) / cs, (y0 + h - oy) / cs
    )
    # the surface sampled densely within each box lies between its bounds
    s = rng.random((2, 200, 400))
    z = terrain.height(x0[:, None] + s[0] * w[:, None], y0[:, None] + s[1] * h[:, None])
    assert np.all(z.max(axis=1) <= high + 1e-6)
    assert np.all(z.min(axis=1) >= low - 1e-6)
    assert np.mean(high - low) < 0.5 * float(np.ptp(terrain.grid))  # and they are local


def test_pinhole_rays_must_point_down():
    terrain = terrain_of(np.zeros_like(X))
    rays = np.zeros((4, 4, 3))
    rays[..., 2] = -1.0
    rays[0, 0, 2] = 0.1  # one ray looking up
    with pytest.raises(ValueError, match="directions"):
        cast_pinhole_rays(HeightBounds(terrain), [0.0, 0.0, 10.0], rays)
    rays[0, 0, 2] = -1.0
    np.testing.assert_allclose(cast_pinhole_rays(HeightBounds(terrain), [0, 0, 10.0], rays), 10)


def test_compiled_bilinear_heights_are_opencv_remap_bit_for_bit():
    # The compiled march samples heights as OpenCV's remap does (float32, INTER_LINEAR,
    # BORDER_REPLICATE: floor, fractions, fused multiply-adds), so depths rendered before
    # and after the march was compiled are the same bits; OpenCV is the oracle.
    import cv2
    from numba import njit

    from sitl.sensors import march

    if not cv2.checkHardwareSupport(12):  # CV_CPU_FMA3: remap blends without fusing
        pytest.skip("OpenCV's remap does not use fused multiply-adds on this CPU")

    @njit
    def heights(grid, u, v):
        return np.array([march.bilinear(grid, u[k], v[k]) for k in range(u.size)])

    rng = np.random.default_rng(3)
    grid = (rng.standard_normal((90, 120)) * 5.0).astype(np.float32)
    u = rng.uniform(-4.0, 124.0, 64 * 80).astype(np.float32)  # edges and beyond included
    v = rng.uniform(-4.0, 94.0, 64 * 80).astype(np.float32)
    expected = cv2.remap(grid, u.reshape(64, 80), v.reshape(64, 80), cv2.INTER_LINEAR,
                         borderMode=cv2.BORDER_REPLICATE).ravel()
    np.testing.assert_array_equal(heights(grid, u, v), expected)


def test_levels_of_detail_are_the_block_means_numpy_computes_bit_for_bit():
    # A distant camera renders the mean-height levels; their heights (so every depth
    # rendered from them) are those of numpy's mean over 2 x 2 blocks in float64 (edge
    # cells repeated to fill the last blocks), on heights of wildly different magnitudes
    # where the summation order shows, and odd sides.
    rng = np.random.default_rng(8)
    grid = (rng.standard_normal((61, 46)) * 10.0 ** rng.integers(-20, 9, (61, 46)))
    terrain = Terrain(grid, 0.2, origin=(-3.0, 5.0))

    def block_means(a, level):
        a = a.astype(np.float64)
        for _ in range(level):
            a = np.pad(a, ((0, a.shape[0] % 2), (0, a.shape[1] % 2)), mode="edge")
            a = a.reshape(a.shape[0] // 2, 2, a.shape[1] // 2, 2).mean(axis=(1, 3))
        return a.astype(np.float32)

    for level in (1, 2, 3):
        coarse = coarse_terrain(terrain, level)
        np.testing.assert_array_equal(coarse.grid.view(np.int32),
                                      block_means(terrain.grid, level).view(np.int32))
        shift = (2**level - 1) / 2 * 0.2
        assert coarse.origin == (-3.0 + shift, 5.0 + shift)
        assert coarse.cell_size == 0.2 * 2**level


def test_noise_bins_are_the_generators_bytes_and_leave_it_where_bytes_would():
    # The camera's noise draws raw 64-bit outputs where that gives the bytes
    # Generator.bytes gives (so seeded flights keep their noise), and bytes otherwise.
    from sitl.sensors.camera import _noise_bins

    for n, offset in ((65536, 0), (4, 0), (6, 0), (65536, 1), (12, 3)):
        ours, theirs = np.random.default_rng(9), np.random.default_rng(9)
        for g in (ours, theirs):  # a 32-bit half left over when offset is odd
            g.integers(0, 2**32, size=offset, dtype=np.uint32)
            g.standard_normal(3)
        got = _noise_bins(ours, n)
        expected = np.frombuffer(theirs.bytes(2 * n), dtype=np.uint16)
        np.testing.assert_array_equal(got, expected)
        for g in (ours, theirs):  # and what they draw next is the same
            g.bytes(2)
        np.testing.assert_array_equal(ours.integers(0, 2**32, size=5, dtype=np.uint32),
                                      theirs.integers(0, 2**32, size=5, dtype=np.uint32))
        assert ours.standard_normal() == theirs.standard_normal()
