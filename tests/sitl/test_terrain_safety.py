"""Ground-truth landing safety on constructed terrains."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from sitl.terrain import Terrain
from sitl.terrain.safety import SafetySettings, is_safe, safety_map

CELL = 0.1
AXIS = np.arange(-8.0, 8.0 + CELL / 2, CELL)
X, Y = np.meshgrid(AXIS, AXIS)


def terrain_of(heights: np.ndarray) -> Terrain:
    return Terrain(heights, CELL, origin=(AXIS[0], AXIS[0]))


def ramp(deg: float) -> Terrain:
    return terrain_of(np.tan(np.radians(deg)) * (0.6 * X + 0.8 * Y))


def test_flat_plane_is_safe_everywhere():
    terrain = terrain_of(np.zeros_like(X))
    mask, slope, roughness = safety_map(terrain)
    assert mask.all()
    assert np.allclose(slope, 0) and np.allclose(roughness, 0)
    assert is_safe(terrain, 0.0, 0.0) is True


def test_box_of_30_cm_inside_the_footprint_is_unsafe():
    box = (np.abs(X - 0.4) <= 0.25) & (np.abs(Y + 0.3) <= 0.25)
    terrain = terrain_of(np.where(box, 0.3, 0.0))
    assert not is_safe(terrain, 0.0, 0.0)
    assert is_safe(terrain, 5.0, 5.0)
    _, _, roughness = safety_map(terrain, region=(-0.05, 0.05, -0.05, 0.05))
    assert roughness.max() > 0.1


def test_low_pebble_is_safe():
    pebble = (np.abs(X - 0.4) <= 0.15) & (np.abs(Y) <= 0.15)
    assert is_safe(terrain_of(np.where(pebble, 0.05, 0.0)), 0.0, 0.0)


def test_obstacle_in_the_clearance_margin_is_unsafe_but_farther_away_it_is_not():
    # a 1 m tall post 1.3 m east: outside the 1 m footprint, inside footprint + 0.5 m margin
    post = (np.abs(X - 1.3) <= 0.1) & (np.abs(Y) <= 0.1)
    terrain = terrain_of(np.where(post, 1.0, 0.0))
    assert not is_safe(terrain, 0.0, 0.0)
    assert is_safe(terrain, -1.5, 0.0)


def test_30_degree_ramp_is_unsafe_and_10_degree_ramp_is_safe():
    steep, gentle = ramp(30.0), ramp(10.0)
    assert not is_safe(steep, 0.0, 0.0)
    assert is_safe(gentle, 0.0, 0.0)
    _, slope, roughness = safety_map(gentle, region=(-1, 1, -1, 1))
    np.testing.assert_allclose(np.degrees(slope), 10.0, atol=0.01)
    assert roughness.max() < 1e-3


def test_slope_limit_is_a_setting():
    strict = SafetySettings(max_slope_deg=5.0)
    assert not is_safe(ramp(10.0), 0.0, 0.0, strict)


def test_points_agree_with_the_map_and_vectorise():
    rng = np.random.default_rng(1)
    heights = np.zeros_like(X)
    for cx, cy in rng.uniform(-6, 6, (12, 2)):
        heights[(np.abs(X - cx) <= 0.3) & (np.abs(Y - cy) <= 0.3)] = 0.4
    terrain = terrain_of(heights)
    mask, _, _ = safety_map(terrain)
    px, py = rng.uniform(-7.9, 7.9, (2, 300))
    row, col = terrain.index(px, py)
    verdict = is_safe(terrain, px, py)
    assert verdict.shape == (300,)
    np.testing.assert_array_equal(verdict, mask[row, col])
    assert 0 < verdict.sum() < 300


def test_region_map_equals_the_whole_map_there():
    rng = np.random.default_rng(2)
    terrain = terrain_of(rng.normal(0, 0.05, X.shape))
    whole = safety_map(terrain)
    rows, cols = terrain.window((-3.0, 2.0, -1.0, 4.0))
    part = safety_map(terrain, region=(-3.0, 2.0, -1.0, 4.0))
    for a, b in zip(whole, part, strict=True):
        np.testing.assert_allclose(a[rows, cols], b, atol=1e-6)


def test_points_outside_the_terrain_or_nan_are_unsafe():
    terrain = terrain_of(np.zeros_like(X))
    np.testing.assert_array_equal(
        is_safe(terrain, [100.0, np.nan, 0.0], [0.0, 0.0, 0.0]), [False, False, True]
    )


def test_bad_safety_settings_name_the_field():
    with pytest.raises(ValidationError, match="max_slope_deg"):
        SafetySettings(max_slope_deg=95)
