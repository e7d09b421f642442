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


@pytest.mark.parametrize("steep_deg", [30.0, 20.0])
def test_a_steep_ramp_is_unsafe_and_a_10_degree_ramp_is_safe(steep_deg):
    steep, gentle = ramp(steep_deg), ramp(10.0)
    assert not is_safe(steep, 0.0, 0.0)
    assert is_safe(gentle, 0.0, 0.0)
    for terrain, angle in ((steep, steep_deg), (gentle, 10.0)):
        _, slope, roughness = safety_map(terrain, region=(-1, 1, -1, 1))
        np.testing.assert_allclose(np.degrees(slope), angle, atol=0.01)
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


def rock_at(x: float, y: float, height: float = 0.2, half_cells: int = 0) -> Terrain:
    """A flat plane with one rock: the cell nearest (x, y), or the (2k+1)^2 block around it."""
    heights = np.zeros_like(X)
    terrain = terrain_of(heights)
    row, col = terrain.index(x, y)
    heights[row - half_cells : row + half_cells + 1, col - half_cells : col + half_cells + 1] = (
        height
    )
    return terrain_of(heights)


@pytest.mark.parametrize("half_cells", [0, 1])
def test_rock_diagonally_outside_the_clearance_disk_is_safe(half_cells):
    # 1.84 m away (1.70 m to the block's nearest corner): outside the 1.5 m clearance disk,
    # inside the square circumscribing it
    terrain = rock_at(1.3, 1.3, half_cells=half_cells)
    assert is_safe(terrain, 0.0, 0.0)
    assert is_safe(terrain, [0.0, 2.6, 0.0, 2.6], [0.0, 0.0, 2.6, 2.6]).all()
    assert not is_safe(terrain, 1.3, 1.3)


@pytest.mark.parametrize("half_cells", [0, 1])
def test_rock_inside_the_clearance_disk_is_unsafe(half_cells):
    # 1.35 m away: outside the 1 m footprint, inside the 1.5 m clearance disk
    terrain = rock_at(1.0, 0.9, half_cells=half_cells)
    assert not is_safe(terrain, 0.0, 0.0)
    _, _, roughness = safety_map(terrain, region=(-0.01, 0.01, -0.01, 0.01))
    assert roughness.item() < 0.1  # it is the clearance that fails, not the footprint
    assert not is_safe(terrain, 0.0, 0.0, SafetySettings())
    assert is_safe(terrain, 0.0, 0.0, SafetySettings(clearance_margin=0.0))


def test_rock_inside_the_footprint_is_unsafe_by_roughness():
    terrain = rock_at(0.5, 0.0)
    assert not is_safe(terrain, 0.0, 0.0)
    assert not is_safe(terrain, 0.0, 0.0, SafetySettings(clearance_margin=0.0))
    _, _, roughness = safety_map(terrain, region=(-0.01, 0.01, -0.01, 0.01))
    assert roughness.item() == pytest.approx(0.2, abs=0.01)


def test_footprint_roughness_is_a_disk_not_its_square():
    # 1.13 m away on the diagonal: inside the square around the 1 m footprint, outside the disk
    _, _, roughness = safety_map(rock_at(0.8, 0.8), region=(-0.01, 0.01, -0.01, 0.01))
    assert roughness.item() < 0.01


def test_clearance_disk_includes_cells_on_its_rim():
    # 0.25 m cells: the 1.5 m clearance disk is 6 cells; offsets with dx^2 + dy^2 <= 36 count
    axis = np.arange(-6.0, 6.0 + 0.125, 0.25)
    xx, yy = np.meshgrid(axis, axis)

    def rock(x, y):
        heights = np.where(np.hypot(xx - x, yy - y) < 0.01, 0.3, 0.0)
        return Terrain(heights, 0.25, origin=(axis[0], axis[0]))

    assert not is_safe(rock(1.5, 0.0), 0.0, 0.0)  # on the rim
    assert not is_safe(rock(1.25, 0.75), 0.0, 0.0)  # 1.46 m
    assert is_safe(rock(1.25, 1.0), 0.0, 0.0)  # 1.60 m
    assert is_safe(rock(1.75, 0.0), 0.0, 0.0)


def rocky(seed: int, shape=(61, 67)) -> Terrain:
    """Gently sloping ground with single-cell and block rocks of 0 .. 40 cm."""
    rng = np.random.default_rng(seed)
    heights = 0.05 * np.arange(shape[1])[None, :] * CELL + rng.normal(0, 0.01, shape)
    rows, cols = rng.integers(0, shape[0], 8), rng.integers(0, shape[1], 8)
    heights[rows, cols] += rng.uniform(0, 0.4, 8)
    for r, c in zip(rows[:3], cols[:3], strict=True):
        heights[r : r + 3, c : c + 2] += 0.25
    return Terrain(heights, CELL, origin=(-3.0, -2.0))


def test_every_cell_agrees_with_the_map_up_to_the_edges():
    terrain = rocky(3)
    mask, _, _ = safety_map(terrain)
    xs, ys = terrain.coordinates()
    gx, gy = np.meshgrid(xs, ys)
    verdict = is_safe(terrain, gx, gy)
    assert verdict.shape == terrain.shape
    np.testing.assert_array_equal(verdict, mask)
    assert 0.1 < mask.mean() < 0.9


@pytest.mark.parametrize(
    "region", [(-2.0, 1.0, -1.0, 1.5), (-3.5, -1.0, -2.5, 0.0), (2.0, 9.0, 2.5, 9.0)]
)
def test_windows_at_the_edges_equal_the_whole_map_there(region):
    terrain = rocky(4)
    whole = safety_map(terrain)
    rows, cols = terrain.window(region)
    part = safety_map(terrain, region=region)
    np.testing.assert_array_equal(whole[0][rows, cols], part[0])
    for a, b in zip(whole[1:], part[1:], strict=True):
        np.testing.assert_allclose(a[rows, cols], b, atol=1e-6)


def test_map_dtypes_and_shapes():
    mask, slope, roughness = safety_map(rocky(5), region=(-1.0, 0.5, -1.0, 0.0))
    assert mask.dtype == bool and slope.dtype == roughness.dtype == np.float32
    assert mask.shape == slope.shape == roughness.shape == (11, 16)


def test_single_points_agree_with_the_map_up_to_the_edges():
    # one point per call: each is judged on its own patch, not on a map
    terrain = rocky(6, shape=(121, 131))
    mask, _, _ = safety_map(terrain)
    xs, ys = terrain.coordinates()
    rng = np.random.default_rng(6)
    rows = np.r_[0, 0, 120, 120, 1, 60, rng.integers(0, 121, 60)]
    cols = np.r_[0, 130, 0, 130, 129, 2, rng.integers(0, 131, 60)]
    verdicts = [is_safe(terrain, xs[c], ys[r]) for r, c in zip(rows, cols, strict=True)]
    np.testing.assert_array_equal(verdicts, mask[rows, cols])
    assert 0 < sum(verdicts) < len(verdicts)
    # a few far-apart points at once: one patch each, all in one stack
    corners = is_safe(terrain, xs[cols[:5]], ys[rows[:5]])
    np.testing.assert_array_equal(corners, mask[rows[:5], cols[:5]])


def reference_map(terrain: Terrain, settings: SafetySettings):
    """The definitions, written with scipy's generic disk filters (slow, obviously right)."""
    from scipy import ndimage

    def disk(radius):
        r = radius / terrain.cell_size
        d = np.arange(-int(r + 1e-9), int(r + 1e-9) + 1)
        return d, (d[None, :] ** 2 + d[:, None] ** 2) <= r * r + 1e-9

    z = terrain.grid.astype(np.float64)
    d, foot = disk(settings.footprint_radius)
    dx = np.where(foot, d[None, :] * terrain.cell_size, 0.0)
    mean = ndimage.correlate(z, foot / foot.sum(), mode="nearest")
    gx = ndimage.correlate(z, dx / np.sum(dx**2), mode="nearest")
    gy = ndimage.correlate(z, dx.T / np.sum(dx**2), mode="nearest")
    slope = np.arctan(np.hypot(gx, gy))
    roughness = ndimage.maximum_filter(np.abs(z - mean), footprint=foot, mode="nearest")
    _, clear = disk(settings.footprint_radius + settings.clearance_margin)
    obstacle = ndimage.maximum_filter(z - mean, footprint=clear, mode="nearest")
    mask = (
        (slope <= np.radians(settings.max_slope_deg))
        & (roughness <= settings.max_rock_height)
        & (obstacle <= settings.max_rock_height)
    )
    return mask, slope, roughness


@pytest.mark.parametrize(
    ("cell", "settings"),
    [
        (0.1, SafetySettings()),
        (0.2, SafetySettings()),  # clearance 7.5 cells
        (0.25, SafetySettings(footprint_radius=0.8, clearance_margin=0.7, max_slope_deg=5.0)),
    ],
)
def test_map_follows_the_disk_definitions(cell, settings):
    rng = np.random.default_rng(7)
    heights = rng.normal(0, 0.03, (57, 63)) + 0.05 * np.arange(63)[None, :] * cell
    heights[rng.integers(0, 57, 12), rng.integers(0, 63, 12)] += rng.uniform(0, 0.4, 12)
    terrain = Terrain(heights, cell, origin=(-5.0, -4.0))
    expected = reference_map(terrain, settings)
    got = safety_map(terrain, settings=settings)
    np.testing.assert_array_equal(got[0], expected[0])
    np.testing.assert_allclose(got[1], expected[1], atol=1e-6)
    np.testing.assert_allclose(got[2], expected[2], atol=1e-6)
    assert 0.05 < got[0].mean() < 0.95
