"""Depth-image costmap detector on constructed depth images with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from lsd.depth_costmap.detector import (
    DenseSites,
    DepthCostmapDetector,
    DepthCostmapSettings,
    SiteList,
    cluster_sites,
    compute_costmaps,
    footprint_depth,
)
from lsd.frames import DepthFrame, Intrinsics

K = Intrinsics(fx=320.0, fy=320.0, cx=319.5, cy=239.5, width=640, height=480)
NADIR = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # camera x east, y south, z down
ALT = 20.0


def rays(rotation, k=K):
    """(H, W, 3) world direction of each pixel's ray per metre of depth."""
    u = np.arange(k.width, dtype=np.float64)[None, :]
    v = np.arange(k.height, dtype=np.float64)[:, None]
    cam = np.stack(np.broadcast_arrays((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0), axis=-1)
    return cam @ np.asarray(rotation).T


def plane_depth(normal, offset, position, rotation, k=K):
    """Depth image of the plane normal . p = offset."""
    r = rays(rotation, k)
    n = np.asarray(normal, dtype=np.float64)
    return (offset - n @ position) / (r @ n)


def render(position=(0.0, 0.0, ALT), rotation=NADIR, box=None, ramp_deg=None):
    """Depth of flat ground (or a ramp rising along x) with an optional box
    (centre x, centre y, half side, height) seen from above."""
    pos = np.asarray(position, dtype=np.float64)
    if ramp_deg is None:
        depth = plane_depth((0, 0, 1), 0.0, pos, rotation)
    else:
        depth = plane_depth((-math.tan(math.radians(ramp_deg)), 0, 1), 0.0, pos, rotation)
    if box is not None:
        bx, by, hs, h = box
        top = plane_depth((0, 0, 1), h, pos, rotation)
        hit = pos + rays(rotation) * top[..., None]
        inside = (np.abs(hit[..., 0] - bx) <= hs) & (np.abs(hit[..., 1] - by) <= hs)
        depth = np.where(inside & (top < depth), top, depth)
    return depth.astype(np.float32)


def frame(depth, position=(0.0, 0.0, ALT), rotation=NADIR, k=K, sigma=None, t=0.0):
    return DepthFrame(depth, sigma, k, np.asarray(position, float), np.asarray(rotation), t)


BOX = (5.0, 0.0, 2.0, 2.0)


def horizontal_distance_to_box(xy, box=BOX):
    bx, by, hs, _ = box
    dx = np.maximum(np.abs(xy[:, 0] - bx) - hs, 0.0)
    dy = np.maximum(np.abs(xy[:, 1] - by) - hs, 0.0)
    return np.hypot(dx, dy)


def test_flat_ground_with_box_sites_only_on_the_ground_clear_of_the_box():
    settings = DepthCostmapSettings(vehicle_radius=1.0)
    det = DepthCostmapDetector(settings)
    obs = det.process(frame(render(box=BOX), t=3.0))
    dense = det.last_sites
    assert len(dense) > 50 and obs
    np.testing.assert_allclose(dense.positions[:, 2], 0.0, atol=1e-3)
    # Footprint clear of the box edge (within one pixel at 18-20 m).
    pixel = ALT / K.fx
    assert horizontal_distance_to_box(dense.positions).min() >= 1.0 - 2 * pixel
    assert np.all(dense.size >= 1.0 - 2 * pixel)
    # The box edges are depth edges: flatness is zero there.
    maps = det.last_maps
    assert maps.flatness_px.min() == 0.0
    for o in obs:
        assert o.source == "depth_costmap" and o.timestamp == 3.0
        assert o.observation_altitude == pytest.approx(ALT - o.z, abs=1e-3)
        assert 0 <= o.roughness <= 1 and 0 <= o.uncertainty <= 1
        assert o.obstacle_altitude >= o.z
    near = horizontal_distance_to_box(np.array([[o.x, o.y] for o in obs])) < 1.0 + 0.5 + 0.5
    assert all(o.obstacle_altitude == pytest.approx(2.0, abs=1e-3)
               for o, n in zip(obs, near, strict=True) if n)


def test_clearance_margin_keeps_sites_off_edges_but_not_off_the_image_border():
    pixel = ALT / K.fx
    gaps, extent = {}, {}
    for margin in (0.0, 1.5):
        # Sites wherever the footprint fits (threshold 0): the image border limits them.
        det = DepthCostmapDetector(DepthCostmapSettings(vehicle_radius=1.0, threshold=0.0,
                                                        clearance_margin=margin))
        det.process(frame(render(box=BOX)))
        pos = det.last_sites.positions
        ground = pos[pos[:, 2] < 1.0]  # the box top (2 m) is flat too
        gaps[margin] = horizontal_distance_to_box(ground).min()
        extent[margin] = pos[:, 0].min()
    # (The box wall facing the camera is seen; its top is the depth edge, so the ground
    # sites keep their distances from that edge: perspective shortens the first gap.)
    assert gaps[1.5] >= gaps[0.0] + 1.5 - 2 * pixel
    # Image border at x = -20 m: only the footprint (1 m) must fit, whatever the margin.
    assert extent[0.0] == extent[1.5] < -20.0 + 1.0 + 0.5


def test_thirty_degree_ramp_gives_no_site_and_a_gentle_one_does():
    det = DepthCostmapDetector()
    assert det.process(frame(render(ramp_deg=30.0))) == []
    maps = det.last_maps
    theta = math.radians(30.0)
    expected = math.exp(-(theta**2) / (2 * math.radians(15.0) ** 2))
    centre = maps.steepness[200:280, 280:360]
    np.testing.assert_allclose(centre, expected, atol=0.01)
    assert DepthCostmapDetector().process(frame(render(ramp_deg=5.0)))


def test_depth_noise_alone_makes_no_edges_but_a_box_on_noisy_ground_still_does():
    rng = np.random.default_rng(0)
    noise = rng.normal(0.0, 0.15, (K.height, K.width)).astype(np.float32)
    det = DepthCostmapDetector(DepthCostmapSettings(vehicle_radius=1.0))
    assert det.process(frame(render(box=BOX) + noise))
    # The box's 2 m step is an edge, the noise is not: sites only clear of the box.
    assert horizontal_distance_to_box(det.last_sites.positions).min() >= 1.0 - 0.2
    assert det.last_maps.flatness_px.max() > 100
    # Thresholds in metres alone (no noise adaptation): the noise is edges everywhere.
    fixed = DepthCostmapDetector(DepthCostmapSettings(vehicle_radius=1.0, edge_noise_factor=0))
    assert fixed.process(frame(render(box=BOX) + noise)) == []
    assert fixed.last_maps.flatness_px.max() < 10


def test_site_heights_average_the_footprint_so_noisy_ground_stays_one_cluster():
    rng = np.random.default_rng(3)
    noise = rng.normal(0.0, 0.15, (K.height, K.width)).astype(np.float32)
    det = DepthCostmapDetector()
    det.process(frame(render() + noise))
    z = det.last_sites.positions[:, 2]
    # Per-pixel noise 15 cm; footprint means (~20 x 20 px at 20 m) bring it to ~1 cm.
    assert len(z) > 50 and np.std(z) < 0.02 and abs(np.mean(z)) < 0.01
    assert len(det.clusters()) < len(det.site_list) / 5


def test_low_hover_over_noisy_stereo_depth_redetects_the_ground_below():
    # The verification look: 2.5 m over flat ground, 256 x 256 px, f = 256 px, stereo noise
    # sigma = z^2 / (f b) * 0.5 px with b = 0.2 m (~6 cm).
    k = Intrinsics(fx=256.0, fy=256.0, cx=127.5, cy=127.5, width=256, height=256)
    pos = (3.0, -2.0, 2.5)
    depth = plane_depth((0, 0, 1), 0.0, np.asarray(pos), NADIR, k).astype(np.float32)
    sigma = np.float32(2.5**2 / (256 * 0.2) * 0.5)
    depth += sigma * np.random.default_rng(5).standard_normal(depth.shape, dtype=np.float32)
    det = DepthCostmapDetector()
    obs = det.process(frame(depth, position=pos, k=k))
    assert obs
    below = min(obs, key=lambda o: math.hypot(o.x - pos[0], o.y - pos[1]))
    assert math.hypot(below.x - pos[0], below.y - pos[1]) < 1.0
    assert below.observation_altitude == pytest.approx(2.5, abs=0.3)
    # Its footprint fits: the inscribed circle is at least the vehicle radius.
    assert det.last_sites.size.min() >= DepthCostmapSettings().vehicle_radius


@pytest.mark.parametrize("altitude", [0.06, 0.3, 1.0])
def test_very_near_ground_is_handled_without_error(altitude):
    # Near depth projects the footprint wider than the image: no site, and no exception.
    k = Intrinsics(fx=256.0, fy=256.0, cx=127.5, cy=127.5, width=256, height=256)
    pos = (0.0, 0.0, altitude)
    depth = plane_depth((0, 0, 1), 0.0, np.asarray(pos), NADIR, k).astype(np.float32)
    det = DepthCostmapDetector()
    assert det.process(frame(depth, position=pos, k=k)) == []
    assert det.counters["frames"] == 1 and det.counters["frames_dropped"] == 0


def test_a_small_step_is_an_edge_on_clean_depth_and_not_below_edge_step():
    depth = render()
    step = depth.copy()
    step[:, 320:] -= 0.3  # a 0.3 m ledge down the middle of the image
    small = depth.copy()
    small[:, 320:] -= 0.05
    det = DepthCostmapDetector()
    det.process(frame(step))
    assert det.last_maps.flatness_px[240, 318:322].min() == 0.0
    det.process(frame(small))
    assert det.last_maps.flatness_px[240, 320] > 50


def test_tilted_camera_still_sees_level_ground_as_level():
    tilt = math.radians(20.0)
    roll = np.array(
        [[1, 0, 0], [0, math.cos(tilt), -math.sin(tilt)], [0, math.sin(tilt), math.cos(tilt)]]
    )
    rot = NADIR @ roll
    det = DepthCostmapDetector()
    obs = det.process(frame(render(rotation=rot), rotation=rot))
    assert obs
    centre = det.last_maps.steepness[200:280, 280:360]
    np.testing.assert_allclose(centre, 1.0, atol=1e-3)
    np.testing.assert_allclose(det.last_sites.positions[:, 2], 0.0, atol=1e-3)


def test_eq1_depth_accuracy_and_energy_prefer_near_pixels():
    maps = compute_costmaps(frame(render(ramp_deg=10.0)), DepthCostmapSettings())
    # The ramp rises towards +x (image right): right is nearer to the camera.
    assert maps.depth_accuracy[240, 600] > maps.depth_accuracy[240, 40]
    assert maps.energy[240, 600] > maps.energy[240, 40]
    for m in (maps.depth_accuracy, maps.flatness, maps.energy, maps.decision):
        assert m.min() >= 0.0 and m.max() <= 1.0 + 1e-6


def test_zero_and_nan_depth_are_invalid_and_no_site_touches_them():
    depth = render()
    depth[200:280, 280:360] = 0.0
    depth[0:40, :] = np.nan
    det = DepthCostmapDetector(DepthCostmapSettings(vehicle_radius=1.0))
    obs = det.process(frame(depth))
    assert obs and det.counters["pixels_invalid"] == 80 * 80 + 40 * 640
    px = det.last_sites.pixels
    footprint_px = K.fx * 1.0 / ALT
    in_hole_rows = (px[:, 0] > 200 - footprint_px) & (px[:, 0] < 280 + footprint_px)
    in_hole_cols = (px[:, 1] > 280 - footprint_px) & (px[:, 1] < 360 + footprint_px)
    assert not np.any(in_hole_rows & in_hole_cols)
    assert px[:, 0].min() >= 40 + footprint_px


def test_depth_beyond_d_max_or_infinite_is_invalid_and_d_max_itself_is_valid():
    depth = render()
    s = DepthCostmapSettings(d_max=float(depth[240, 320]))
    depth[0:10, :] = np.inf
    depth[10:20, :] = np.float32(s.d_max) * 1.01
    depth[240, 320] = np.float32(s.d_max)
    maps = compute_costmaps(frame(depth), s)
    assert not maps.valid[0:20].any()
    assert maps.valid[240, 320]
    assert np.isneginf(maps.world_z[0:20]).all() and (maps.decision[0:20] == 0).all()
    assert maps.depth_range[1] == pytest.approx(s.d_max)


def test_frames_processed_from_several_threads_give_the_maps_of_serial_processing():
    from concurrent.futures import ThreadPoolExecutor

    s = DepthCostmapSettings()
    frames = [frame(render(box=(2.0 * i - 3.0, 1.0, 1.5, 2.0))) for i in range(4)]
    serial = [compute_costmaps(f, s) for f in frames]
    with ThreadPoolExecutor(max_workers=4) as pool:
        parallel = list(pool.map(lambda f: compute_costmaps(f, s), frames * 2))
    for a, b in zip(serial * 2, parallel, strict=True):
        for name in ("valid", "world_z", "flatness_px", "clearance_px", "flatness"):
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
        # OpenCV splits its box blur into stripes by the threads free at the time: the
        # normals may differ in the last bit, no more.
        for name in ("steepness", "decision"):
            np.testing.assert_allclose(getattr(a, name), getattr(b, name), rtol=0, atol=1e-6)
    # The box moves between frames: the flatness maps differ (the check is not vacuous).
    assert not np.array_equal(serial[0].flatness_px, serial[3].flatness_px)


@pytest.mark.parametrize("hole", [False, True])
def test_footprint_depth_of_a_tilted_plane_is_its_centre_depth_with_or_without_holes(hole):
    tilt = np.array([[1.0, 0, 0], [0, -0.9659258, -0.2588190], [0, 0.2588190, -0.9659258]])
    depth = render(rotation=NADIR @ tilt.T)
    valid = np.ones(depth.shape, dtype=bool)
    if hole:  # invalid pixels (NaN) far from the sites are ignored
        depth[:50, :] = np.nan
        valid[:50, :] = False
    rows, cols = np.array([120, 240, 400]), np.array([100, 320, 600])
    d = footprint_depth(depth, valid, rows, cols, K.fx * 1.0)
    np.testing.assert_allclose(d, depth[rows, cols], rtol=1e-5)


def _maps_in_child(conn, depth):
    maps = compute_costmaps(frame(depth), DepthCostmapSettings())
    conn.send(maps.flatness_px)
    conn.close()


def test_a_forked_process_computes_maps_after_its_parent_did():
    import multiprocessing

    depth = render(box=(0.0, 0.0, 1.5, 2.0))
    parent_maps = compute_costmaps(frame(depth), DepthCostmapSettings())
    ctx = multiprocessing.get_context("fork")
    receive, send = ctx.Pipe(duplex=False)
    child = ctx.Process(target=_maps_in_child, args=(send, depth))
    child.start()
    try:
        assert receive.poll(60), "the child never finished its costmaps"
        np.testing.assert_array_equal(receive.recv(), parent_maps.flatness_px)
    finally:
        child.join(10)
        if child.is_alive():
            child.kill()
        receive.close()
    assert child.exitcode == 0


@pytest.mark.parametrize(
    "k",
    [
        Intrinsics(fx=0.0, fy=320.0, cx=319.5, cy=239.5, width=640, height=480),
        Intrinsics(fx=320.0, fy=-1.0, cx=319.5, cy=239.5, width=640, height=480),
        Intrinsics(fx=float("nan"), fy=320.0, cx=319.5, cy=239.5, width=640, height=480),
    ],
)
def test_bad_intrinsics_drop_the_frame_without_raising(k):
    det = DepthCostmapDetector()
    assert det.process(frame(render(), k=k)) == []
    assert det.counters["frames_dropped"] == 1 and "focal" in det.last_problem


def test_bad_pose_or_shape_drops_the_frame():
    det = DepthCostmapDetector()
    assert det.process(frame(render(), position=(0.0, np.nan, 20.0))) == []
    assert det.process(frame(np.zeros(10, dtype=np.float32))) == []
    assert det.process(frame(np.full((480, 640), np.nan, dtype=np.float32))) == []
    assert det.counters["frames_dropped"] == 2


def test_reprocessing_a_frame_adds_no_site_and_redetects_the_same_clusters():
    det = DepthCostmapDetector()
    f = frame(render(box=BOX))
    first = det.process(f)
    n = len(det.site_list)
    second = det.process(f)
    assert len(det.site_list) == n
    assert sorted((round(o.x, 6), round(o.y, 6)) for o in first) == sorted(
        (round(o.x, 6), round(o.y, 6)) for o in second
    )


def sites_at(positions, alt=20.0):
    n = len(positions)
    return DenseSites(
        pixels=np.zeros((n, 2), dtype=np.int64),
        positions=np.asarray(positions, dtype=np.float64),
        score=np.ones(n),
        size=np.ones(n),
        roughness=np.zeros(n),
        uncertainty=np.zeros(n),
        obstacle_altitude=np.zeros(n),
        observation_altitude=np.full(n, alt),
    )


def test_site_list_adds_a_site_only_without_a_neighbour_within_the_threshold():
    lst = SiteList(dedup_distance=0.5, max_sites=100)
    ids = lst.add(sites_at([[0, 0, 0], [0.2, 0, 0], [3, 0, 0]]))
    assert len(lst) == 2
    assert ids[0] == ids[1] and ids[2] != ids[0]
    ids2 = lst.add(sites_at([[0.1, 0.1, 0], [6, 0, 0]], alt=5.0), now=9.0)
    assert len(lst) == 3 and ids2[0] == ids[0]
    # The redetection from lower down refreshed the listed site's properties.
    assert lst.sites.observation_altitude[ids[0]] == 5.0 and lst.timestamp[ids[0]] == 9.0
    pos = lst.sites.positions
    d = np.linalg.norm(pos[:, None] - pos[None], axis=2) + np.eye(len(pos)) * 1e9
    assert d.min() > 0.5


def test_clustering_merges_sites_closer_than_both_thresholds():
    a = [[0, 0, 0], [0.3, 0, 0], [0.6, 0, 0]]  # chain within 0.5 m: one cluster
    b = [[5, 0, 0], [5.3, 0, 0.005]]  # dz 5 mm < 10 mm: one cluster
    c = [[5, 5, 0], [5.3, 5, 0.05]]  # dz 5 cm > 10 mm: two clusters
    labels = cluster_sites(np.array(a + b + c, dtype=float), 0.5, 0.01)
    assert len(set(labels[:3])) == 1 and len(set(labels[3:5])) == 1
    assert labels[5] != labels[6] and len(set(labels)) == 4


def test_hierarchy_and_kdtree_clustering_give_the_same_partition():
    rng = np.random.default_rng(5)
    pts = np.c_[rng.uniform(0, 10, (600, 2)), rng.choice([0.0, 0.5, 1.0], 600)]
    a = cluster_sites(pts, 0.5, 0.01, hierarchy_limit=10_000)
    b = cluster_sites(pts, 0.5, 0.01, hierarchy_limit=2)
    assert len(set(a)) == len(set(b)) > 1
    pairs_a = a[:, None] == a[None, :]
    pairs_b = b[:, None] == b[None, :]
    assert np.array_equal(pairs_a, pairs_b)


def test_clusters_reported_frame_by_frame_are_those_of_the_whole_list():
    # Sites arrive in batches that bridge earlier clusters; each batch's reported clusters
    # must be clusters of the whole list clustered at once (single linkage only merges).
    rng = np.random.default_rng(11)
    det = DepthCostmapDetector(DepthCostmapSettings(dedup_distance=0.1))
    reported = []
    for _ in range(12):
        n = 80
        pos = np.c_[rng.uniform(0, 8, (n, 2)), rng.choice([0.0, 0.005, 1.0], n)]
        batch = DenseSites(
            pixels=np.zeros((n, 2), dtype=np.int64), positions=pos, score=rng.random(n),
            size=np.ones(n), roughness=np.zeros(n), uncertainty=np.zeros(n),
            obstacle_altitude=pos[:, 2].copy(), observation_altitude=np.full(n, 10.0),
        )
        reported.append(det.add_sites(batch))
    whole = {tuple(np.round(o.position, 9)) for o in det.clusters()}
    last = {tuple(np.round(o.position, 9)) for o in reported[-1]}
    assert last and last <= whole
    # The whole list's partition is that of cluster_sites on all listed positions.
    full = cluster_sites(det.site_list.sites.positions, 0.5, 0.01, hierarchy_limit=2)
    assert np.array_equal(det.labels[:, None] == det.labels[None, :],
                          full[:, None] == full[None, :])


def test_detector_returns_cluster_centroids():
    det = DepthCostmapDetector(DepthCostmapSettings(cluster_distance=0.5, cluster_dz=0.01))
    det.process(frame(render()))
    clusters = det.clusters()
    labels = det.labels
    assert len(clusters) == labels.max() + 1 < len(det.site_list)
    for label, site in enumerate(clusters):
        members = det.site_list.sites.positions[labels == label]
        centre = members.mean(axis=0)
        got = np.array(site.position)
        if np.linalg.norm(members - centre, axis=1).min() <= 0.5:
            np.testing.assert_allclose(got, centre, atol=1e-9)  # eq. 8 centroid
        else:  # chained cluster: the member nearest the centroid
            assert np.linalg.norm(members - got, axis=1).min() < 1e-9


def test_frame_sigma_sets_the_uncertainty():
    depth = render()
    sigma = np.full_like(depth, 0.25)
    det = DepthCostmapDetector(DepthCostmapSettings(sigma_ref=1.0))
    obs = det.process(frame(depth, sigma=sigma))
    assert obs and all(o.uncertainty == pytest.approx(0.25) for o in obs)


def test_settings_validation_names_the_field():
    with pytest.raises(ValidationError, match="sum to 1"):
        DepthCostmapSettings(weights={"depth_accuracy": 0.5, "flatness": 0.5, "steepness": 0.5,
                                      "energy": 0.0})
    with pytest.raises(ValidationError, match="d_max"):
        DepthCostmapSettings(d_min=10.0, d_max=5.0)
    with pytest.raises(ValidationError, match="threshold"):
        DepthCostmapSettings(threshold=1.5)


def test_image_size_not_a_multiple_of_the_stride():
    k = Intrinsics(fx=300.0, fy=300.0, cx=150.0, cy=101.0, width=301, height=203)
    pos = np.array([0.0, 0.0, 15.0])
    depth = plane_depth((0, 0, 1), 0.0, pos, NADIR, k).astype(np.float32)
    top = plane_depth((0, 0, 1), 1.0, pos, NADIR, k)
    hit = pos + rays(NADIR, k) * top[..., None]
    post = (np.abs(hit[..., 0] - 4.0) <= 0.5) & (np.abs(hit[..., 1]) <= 0.5)
    depth[post] = top[post]
    det = DepthCostmapDetector(DepthCostmapSettings(vehicle_radius=0.5, obstacle_margin=3.0))
    obs = det.process(frame(depth, position=pos, k=k))
    assert obs
    gap = horizontal_distance_to_box(det.last_sites.positions, (4.0, 0.0, 0.5, 1.0))
    near, far = gap < 3.0, gap > 6.0
    assert near.any() and far.any()
    np.testing.assert_allclose(det.last_sites.obstacle_altitude[near], 1.0, atol=1e-3)
    np.testing.assert_allclose(det.last_sites.obstacle_altitude[far], 0.0, atol=1e-3)


def test_a_frame_reports_only_clusters_near_it_and_clusters_covers_the_whole_list():
    det = DepthCostmapDetector()
    first = det.process(frame(render(position=(0.0, 0.0, ALT)), position=(0.0, 0.0, ALT)))
    far = (200.0, 0.0, ALT)
    second = det.process(frame(render(position=far), position=far))
    assert first and second
    assert all(abs(o.x) < 30 for o in first) and all(abs(o.x - 200.0) < 30 for o in second)
    everything = det.clusters()
    xs = np.array([o.x for o in everything])
    assert (xs < 100).any() and (xs > 100).any()
    assert len(det.labels) == len(det.site_list)
