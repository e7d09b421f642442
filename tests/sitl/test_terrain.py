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
