"""Terrain worlds: the Terrain grid contract and world generation."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from sitl.terrain import Terrain, make_terrain, parse_terrain_settings

SMALL = {"size": (60.0, 50.0), "cell_size": 0.25}


def test_height_is_bilinear_between_cell_centres_and_clamped_outside():
    grid = np.array([[0.0, 1.0, 2.0], [10.0, 11.0, 12.0]])  # h = x + 10 y
    terrain = Terrain(grid, cell_size=2.0, origin=(-2.0, 5.0))
    assert terrain.extent == (-2.0, 2.0, 5.0, 7.0)
    x = np.array([-2.0, -1.0, 0.5, 2.0])
    y = np.array([5.0, 6.0, 5.5, 7.0])
    expected = (x + 2.0) / 2.0 + 10.0 * (y - 5.0) / 2.0
    np.testing.assert_allclose(terrain.height(x, y), expected)
    # broadcasting: (3, 1) x (4,) -> (3, 4)
    assert terrain.height(x[None, :], y[:3, None]).shape == (3, 4)
    # outside: the edge value
    np.testing.assert_allclose(terrain.height([-50.0, 50.0], [6.0, 100.0]), [5.0, 12.0])


def test_flat_world_covers_400_m_at_fine_cells_with_home_at_zero():
    terrain = make_terrain({"kind": "flat"}, seed=0)
    xmin, xmax, ymin, ymax = terrain.extent
    assert xmax - xmin >= 400 and ymax - ymin >= 400
    assert xmin < 0 < xmax and ymin < 0 < ymax
    assert terrain.cell_size <= 0.2
    assert terrain.grid.dtype == np.float32
    assert terrain.grid.shape == (len(terrain.coordinates()[1]), len(terrain.coordinates()[0]))
    assert terrain.height(0.0, 0.0) == 0.0
    assert not terrain.grid.any()


@pytest.mark.parametrize(
    "bad, field",
    [
        ({"kind": "flat", "cell_size": 0}, "cell_size"),
        ({"kind": "flat", "center": (500.0, 0.0)}, "center"),
        ({"kind": "mars", "rock_diameter": (2.0, 1.0)}, "rock_diameter"),
        ({"kind": "urban", "road_width": 90.0}, "road_width"),
        ({"kind": "volcano"}, "kind"),
        ({"kind": "flat", "colour": "red"}, "colour"),
    ],
)
def test_bad_terrain_settings_name_the_field(bad, field):
    with pytest.raises(ValidationError, match=field):
        parse_terrain_settings(bad)


@pytest.mark.parametrize("kind", ["mars", "urban", "rubble"])
def test_procedural_worlds_are_deterministic_per_seed(kind):
    settings = {"kind": kind, **SMALL}
    a = make_terrain(settings, seed=3)
    b = make_terrain(settings, seed=3)
    c = make_terrain(settings, seed=4)
    np.testing.assert_array_equal(a.grid, b.grid)
    assert not np.array_equal(a.grid, c.grid)
    assert a.grid.dtype == np.float32 and a.cell_size == 0.25


@pytest.mark.parametrize("kind", ["flat", "mars", "urban", "rubble"])
@pytest.mark.parametrize("seed", [0, 1])
def test_home_is_at_zero_and_takeoff_safe(kind, seed):
    from sitl.terrain.safety import is_safe

    terrain = make_terrain({"kind": kind, **SMALL}, seed=seed)
    assert terrain.height(0.0, 0.0) == pytest.approx(0.0, abs=1e-6)
    assert is_safe(terrain, 0.0, 0.0)
    assert np.all(is_safe(terrain, [2.0, -2.0, 0.0], [0.0, 2.0, -3.0]))


@pytest.mark.parametrize("kind", ["mars", "urban", "rubble"])
def test_worlds_have_both_safe_and_unsafe_ground(kind):
    from sitl.terrain.safety import safety_map

    terrain = make_terrain({"kind": kind, "size": (120.0, 120.0)}, seed=5)
    mask, slope, roughness = safety_map(terrain)
    assert mask.shape == slope.shape == roughness.shape == terrain.shape
    assert 0.05 < mask.mean() < 0.98


def test_mars_rock_sizes_follow_the_size_frequency_setting():
    from sitl.terrain.features import power_law_sizes

    rng = np.random.default_rng(0)
    sizes = power_law_sizes(200_000, 0.1, 10.0, 2.5, rng)
    assert sizes.min() >= 0.1 and sizes.max() <= 10.0
    # cumulative N(>D) ~ D^-2.5: ten times fewer above 0.1 * 10^(1/2.5) than above 0.1
    ratio = np.mean(sizes > 0.1 * 10 ** (1 / 2.5))
    assert ratio == pytest.approx(0.1, rel=0.05)


def test_more_rocks_make_less_safe_ground():
    from sitl.terrain.safety import safety_map

    base = {"kind": "mars", "size": (100.0, 100.0), "scarp_count": 0, "crater_density": 0}
    sparse = make_terrain({**base, "rock_density": 0.02}, seed=2)
    dense = make_terrain({**base, "rock_density": 0.5}, seed=2)
    assert safety_map(dense)[0].mean() < safety_map(sparse)[0].mean()


def test_npy_elevation_model_round_trip(tmp_path):
    # h = 0.3 x + 0.1 y on a 1 m grid, row i along +y
    ny, nx = 41, 61
    heights = 0.3 * np.arange(nx)[None, :] + 0.1 * np.arange(ny)[:, None]
    path = tmp_path / "dem.npy"
    np.save(path, heights)
    terrain = make_terrain(
        {"kind": "file", "path": str(path), "source_cell_size": 1.0, "home_clear_radius": 0},
        seed=0,
    )
    # home at the model's centre (30, 20) m
    x = np.array([-30.0, 0.0, 12.5, 30.0])
    y = np.array([-20.0, 0.0, -7.3, 20.0])
    np.testing.assert_allclose(terrain.height(x, y), 0.3 * x + 0.1 * y, atol=1e-4)
    assert terrain.cell_size == 0.2


def test_asc_elevation_model_round_trip_north_up_with_nodata(tmp_path):
    ny, nx, cell = 30, 40, 2.0
    heights = 0.5 * np.arange(nx)[None, :] * cell + 0.2 * np.arange(ny)[:, None] * cell
    north_up = heights[::-1].copy()
    north_up[0, 0] = -9999.0  # a hole in the north-west corner
    path = tmp_path / "dem.asc"
    header = (
        f"ncols {nx}\nnrows {ny}\nxllcorner 1000.0\nyllcorner 2000.0\n"
        f"cellsize {cell}\nNODATA_value -9999\n"
    )
    path.write_text(header + "\n".join(" ".join(f"{v:.4f}" for v in row) for row in north_up))
    terrain = make_terrain(
        {
            "kind": "file",
            "path": str(path),
            "home": (10.0, 8.0),
            "home_clear_radius": 0,
            "cell_size": 0.5,
        },
        seed=0,
    )
    # relative to home (10, 8): h(x, y) - h(0, 0) = 0.5 x + 0.2 y
    x = np.array([5.0, -10.0, 40.0])
    y = np.array([3.0, -8.0, 20.0])
    np.testing.assert_allclose(terrain.height(x, y), 0.5 * x + 0.2 * y, atol=1e-4)
    # the hole took a neighbour's height: the corner is finite and close to its neighbours
    corner = terrain.height(-10.0, 58.0 - 8.0)
    assert np.isfinite(corner) and abs(corner - (0.5 * -10 + 0.2 * 50)) < 1.5


def test_bad_elevation_files_are_reported_by_field(tmp_path):
    with pytest.raises(ValidationError, match="path"):
        parse_terrain_settings({"kind": "file", "path": str(tmp_path / "missing.npy")})
    npy = tmp_path / "dem.npy"
    np.save(npy, np.zeros((4, 4)))
    with pytest.raises(ValidationError, match="source_cell_size"):
        parse_terrain_settings({"kind": "file", "path": str(npy)})
    bad = tmp_path / "bad.asc"
    bad.write_text("ncols 3\nnrows 2\ncellsize 1\n1 2 3\n")
    with pytest.raises(ValueError, match="path"):
        make_terrain({"kind": "file", "path": str(bad)}, seed=0)


def test_geotiff_without_rasterio_says_how_to_install_it(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "rasterio", None)  # import fails as if not installed
    path = tmp_path / "dem.tif"
    path.write_bytes(b"II*\x00")
    with pytest.raises(ValueError, match="path: .*rasterio"):
        make_terrain({"kind": "file", "path": str(path)}, seed=0)


def test_mars_craters_are_bowls_with_raised_rims():
    bare = {
        "kind": "mars",
        "size": (200.0, 200.0),
        "relief_rms": 0.0,
        "rock_density": 0.0,
        "scarp_count": 0,
        "home_clear_radius": 0.0,
    }
    plain = make_terrain({**bare, "crater_density": 0.0}, seed=1)
    assert np.ptp(plain.grid) == 0.0
    cratered = make_terrain(
        {**bare, "crater_density": 200.0, "crater_diameter": (20.0, 20.0)}, seed=1
    )
    level = np.median(cratered.grid)
    # bowls about 0.2 D = 4 m deep below the plain, rims about 0.04 D = 0.8 m above it
    assert -5.5 < cratered.grid.min() - level < -3.0
    assert 0.5 < cratered.grid.max() - level < 2.0
