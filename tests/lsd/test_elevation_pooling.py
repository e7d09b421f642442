"""The coarse map analysed on a pooled grid while the camera is high."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lsd.elevation.detector import ElevationDetector
from lsd.elevation.map import ElevationMap, pooled_level
from lsd.elevation.settings import DetectorSettings, ElevationMapSettings
from tests.lsd.test_elevation import assert_valid, flat, render

BOX = (10.0, 6.0)  # centre of a 6 m x 6 m, 3 m high block, world x/y


def block(x, y):
    """Flat ground at z=2 with a 6 m square, 3 m high block."""
    inside = (np.abs(x - BOX[0]) < 3.0) & (np.abs(y - BOX[1]) < 3.0)
    return 2.0 + 3.0 * inside


def test_pooled_level_combines_blocks_by_inverse_variance():
    mean = np.array([[1.0, 3.0, np.nan, np.nan], [np.nan, np.nan, np.nan, np.nan]])
    variance = np.array([[1.0, 3.0, np.inf, np.inf], [np.inf, np.inf, np.inf, np.inf]])
    top = mean + 0.5
    closest = np.array([[10.0, 40.0, np.inf, np.inf], [np.inf, np.inf, np.inf, np.inf]])
    pooled_mean, pooled_var, pooled_top, cell_var, looks = pooled_level(
        mean, variance, top, closest, 2
    )
    assert pooled_mean.shape == (1, 2)
    # Weights 1 and 1/3: (1 * 1 + 3 / 3) / (4 / 3) = 1.5; variance 1 / (4 / 3).
    assert pooled_mean[0, 0] == pytest.approx(1.5)
    assert pooled_var[0, 0] == pytest.approx(0.75)
    assert pooled_top[0, 0] == pytest.approx(2.0)
    assert cell_var[0, 0] == pytest.approx(2.0)  # the plain mean of the cells' variances
    assert looks[0, 0] == pytest.approx(40.0)  # the farthest look of the block
    # A block with no observed cell stays unobserved.
    assert math.isnan(pooled_mean[0, 1]) and math.isinf(pooled_var[0, 1])
    assert math.isnan(pooled_top[0, 1]) and looks[0, 1] == 0.0


def test_pooled_looks_are_each_blocks_farthest_look_in_single_precision():
    rng = np.random.default_rng(12)
    shape = (24, 36)
    mean = rng.normal(5.0, 1.0, shape)
    closest = rng.uniform(1.0, 90.0, shape)
    hidden = rng.random(shape) < 0.4
    hidden[:4, :4] = True  # a block with no observed cell
    mean[hidden] = np.nan
    closest[hidden] = np.inf
    variance = np.where(hidden, np.inf, 0.01)
    looks = pooled_level(mean, variance, mean, closest, 4)[4]
    single = np.where(np.isinf(closest), 0.0, closest).astype(np.float32)
    expected = single.reshape(6, 4, 9, 4).max(axis=(1, 3)).astype(np.float64)
    assert np.array_equal(looks, expected) and looks[0, 0] == 0.0


def test_a_high_camera_analyses_coarser_cells_and_a_low_one_does_not():
    settings = DetectorSettings()
    detector = ElevationDetector(settings=settings)
    resolution = detector.map_settings.resolution
    detector.process(render(flat, (0.0, 0.0, 102.0), n=256, f=256))
    high = detector.last_analysis.resolution
    detector.process(render(flat, (0.0, 0.0, 32.0), n=256, f=256, timestamp=1.0))
    mid = detector.last_analysis.resolution
    assert high > mid >= resolution
    # Never coarser than the footprint nor than max_analysis_pool cells.
    assert high <= min(settings.footprint_radius, settings.max_analysis_pool * resolution)


def test_pooled_sites_keep_a_footprint_away_from_a_block():
    # Every site of the view; an obstacle square that reaches past the nearest ones.
    settings = DetectorSettings(max_sites=1000, obstacle_radius=8.0)
    detector = ElevationDetector(settings=settings)
    observations = detector.process(render(block, (0.0, 0.0, 82.0), n=256, f=256))
    assert detector.last_analysis.resolution > detector.map_settings.resolution
    assert_valid(observations, settings)
    assert len(observations) >= 10
    for o in observations:
        gap = max(abs(o.x - BOX[0]) - 3.0, abs(o.y - BOX[1]) - 3.0)
        assert gap >= settings.footprint_radius
        assert o.z == pytest.approx(2.0, abs=0.05)
    # Sites whose obstacle square (half-side obstacle_radius) reaches the block see it.
    near = [
        o
        for o in observations
        if max(abs(o.x - BOX[0]), abs(o.y - BOX[1])) - 3.0 < settings.obstacle_radius - 0.5
    ]
    assert near and all(o.obstacle_altitude >= 4.9 for o in near)


def test_pooled_sites_stay_put_when_the_vehicle_moves():
    settings = DetectorSettings(max_sites=1000)
    first = ElevationDetector(settings=settings)
    a = first.process(render(flat, (0.0, 0.0, 102.0), n=256, f=256))
    second = ElevationDetector(settings=settings)
    b = second.process(render(flat, (1.3, -0.7, 102.0), n=256, f=256))
    assert second.last_analysis.resolution > second.map_settings.resolution
    a = np.array([(o.x, o.y) for o in a])
    b = np.array([(o.x, o.y) for o in b])
    # Blocks are world-aligned: seen from elsewhere, a site is found again nearby (away
    # from the edges of either view, where the room around a site differs).
    gap = np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1]).min(axis=1)
    overlap = (np.abs(a[:, 0] - 0.65) < 25.0) & (np.abs(a[:, 1] + 0.35) < 25.0)
    assert overlap.sum() >= 10
    assert np.all(gap[overlap] < 1.0)


def test_a_recentring_slack_keeps_the_window_until_the_camera_strays_that_far():
    emap = ElevationMap(ElevationMapSettings(size=20.0, resolution=0.5))
    emap.recentre(0.0, 0.0)
    emap.fuse(np.array([[1.2, -0.7, 3.0]]), np.array([0.01]), now=0.0)
    origin = emap.origin_index.copy()
    assert emap.recentre(4.0, -3.0, slack=5.0) == 0  # within the slack: no move
    assert np.array_equal(emap.origin_index, origin)
    assert emap.recentre(6.0, 0.0, slack=5.0) == 12  # beyond it: centred on the camera
    assert emap.height_at(1.2, -0.7) == pytest.approx(3.0)  # estimates keep their place
    assert emap.cell_of(6.0, 0.0)[0] == 20


def test_pooled_looks_match_the_row_major_reduction_bit_for_bit():
    # The column-first reduction keeps the row-major one's results, signed zeros and NaN too.
    from lsd.elevation.map import _block_looks, _block_looks_in_order

    rng = np.random.default_rng(5)
    values = np.array([0.0, -0.0, np.inf, -np.inf, np.nan, 1.0, 2.5, 1e40, -1.0])
    for trial in range(60):
        shape = tuple(rng.integers(1, 20, 2))
        grid = rng.choice(values, size=shape, p=[0.2, 0.1, 0.2, 0.05, 0.03, 0.17, 0.1, 0.05, 0.1])
        if trial % 2:
            grid[np.signbit(grid) & (grid == 0)] = 0.0  # no -0: the column-first path
        factor = int(rng.integers(1, 5))
        got, want = _block_looks(grid, factor), _block_looks_in_order(grid, factor)
        assert got.shape == want.shape
        assert np.array_equal(np.isnan(got), np.isnan(want))
        finite = ~np.isnan(want)
        assert np.array_equal(got[finite].view(np.int64), want[finite].view(np.int64))
