"""Site selection from a size grid (:func:`lsd.site_selection.select_sites`): one site per
world-aligned block, never on ground smaller than the footprint, best first."""

from __future__ import annotations

import numpy as np

from lsd.elevation.settings import DetectorSettings
from lsd.site_selection import cells_at_least, select_sites, site_size

RESOLUTION = 0.1  # m per cell


def _discs(shape, discs):
    i, j = np.indices(shape)
    safe = np.zeros(shape, bool)
    for ci, cj, radius in discs:
        safe |= np.hypot(i - ci, j - cj) <= radius
    return safe


def test_sites_lie_on_ground_wider_than_the_footprint_one_per_block_best_first():
    settings = DetectorSettings()  # footprint 1 m, blocks of 4 m
    # A 3 m disc, a 1.5 m disc and a 0.6 m one (narrower than the footprint).
    safe = _discs((240, 240), [(60, 60, 30), (170, 170, 15), (60, 190, 6)])
    size = site_size(safe, RESOLUTION)
    i, j = select_sites(size, np.zeros(size.shape, np.float32), (0, 0), RESOLUTION, settings)

    assert 2 <= len(i) <= settings.max_sites
    assert (size[i, j] >= settings.footprint_radius).all()
    assert not (np.hypot(i - 60, j - 190) <= 6).any()  # nothing on the narrow disc
    assert np.hypot(i[0] - 60, j[0] - 60) < 5  # the widest ground's centre comes first
    block = round(settings.site_spacing / RESOLUTION)
    keys = list(zip(i // block, j // block, strict=True))
    assert len(set(keys)) == len(keys)
    # Suppressed within half a block of a better site: no two sites crowd a block border.
    d = np.hypot(i[:, None] - i[None, :], j[:, None] - j[None, :])
    assert d[~np.eye(len(i), dtype=bool)].min() >= block / 2


def test_blocks_are_world_aligned_so_a_shifted_view_keeps_its_sites():
    settings = DetectorSettings()
    safe = _discs((240, 240), [(120, 120, 70)])
    size = site_size(safe, RESOLUTION)
    quality = np.zeros(size.shape, np.float32)
    i, j = select_sites(size, quality, (0, 0), RESOLUTION, settings)
    # The same ground seen 7 and 13 cells further on: its grid starts at world cell (7, 13).
    i2, j2 = select_sites(size[7:, 13:], quality[7:, 13:], (7, 13), RESOLUTION, settings)
    world = {(a, b) for a, b in zip(i, j, strict=True)}
    shifted = {(a + 7, b + 13) for a, b in zip(i2, j2, strict=True)}
    inside = {(a, b) for a, b in world if a >= 7 + 40 and b >= 13 + 40}  # away from the cut
    assert inside and inside <= shifted


def test_no_ground_wide_enough_gives_no_site():
    settings = DetectorSettings()
    size = site_size(_discs((80, 80), [(40, 40, 8)]), RESOLUTION)
    i, j = select_sites(size, np.zeros(size.shape, np.float32), (0, 0), RESOLUTION, settings)
    assert len(i) == len(j) == 0


def test_cells_at_least_are_numpys_nonzero_in_row_major_order():
    rng = np.random.default_rng(4)
    grid = rng.uniform(0.0, 2.0, (37, 53))
    grid[rng.random(grid.shape) < 0.1] = np.nan  # never at least anything
    flat, rows, cols = cells_at_least(grid, 1.0)
    want_rows, want_cols = np.nonzero(grid >= 1.0)
    assert np.array_equal(rows, want_rows) and np.array_equal(cols, want_cols)
    assert np.array_equal(flat, np.flatnonzero(grid >= 1.0))
    assert all(len(a) == 0 for a in cells_at_least(grid, 3.0))


def test_maximum_box_is_scipys_maximum_filter():
    from scipy import ndimage

    from lsd.site_selection import maximum_box

    rng = np.random.default_rng(5)
    for shape, size in [((40, 33), 21), ((7, 90), 5), ((64, 64), 3), ((5, 5), 11)]:
        values = rng.normal(0.0, 10.0, shape).astype(np.float32)
        values[rng.random(shape) < 0.1] = -np.inf
        for grid in (values, rng.integers(0, 3, shape).astype(np.uint8)):
            expected = ndimage.maximum_filter(grid, size=size, mode="nearest")
            assert np.array_equal(maximum_box(grid, size), expected)
