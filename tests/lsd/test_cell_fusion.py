"""The order statistic behind each cell's top (lsd.elevation.cell_fusion) against a sort, and
the in-place shift of a recentred map's grids (lsd.elevation.map) against a copy."""

from __future__ import annotations

import numpy as np

from lsd.elevation.cell_fusion import TOP_QUANTILE, _kth_smallest
from lsd.elevation.map import _shift


def test_kth_smallest_is_the_sorted_value_with_ties_and_past_the_network():
    rng = np.random.default_rng(11)
    for m in list(range(1, 90)) + [200, 1000]:
        for spread in (3, 1 << 40):  # many ties, then almost none
            values = rng.integers(0, spread, m + 7)
            a, b = 3, 3 + m
            ks = {int(TOP_QUANTILE * (m - 1)), 0, m - 1, int(rng.integers(m))}
            for k in ks:
                expected = np.sort(values[a:b])[k]
                got = _kth_smallest(values.copy(), a, b, k)
                assert got == expected, (m, k)


def test_a_recentred_grid_moves_in_place_as_a_copy_would_every_way_and_beyond():
    rng = np.random.default_rng(5)
    for di, dj in [(0, 0), (3, 0), (-3, 0), (0, 4), (0, -4), (2, -5), (-6, 1), (-1, -1),
                   (7, 7), (9, 0), (0, -12), (-20, 3)]:
        grids = (rng.normal(size=(9, 7)), rng.normal(size=(9, 7)))
        fills = (np.nan, -np.inf)
        expected = []
        for g, fill in zip(grids, fills, strict=True):
            out = np.full_like(g, fill)
            for i in range(9):
                for j in range(7):
                    if 0 <= i + di < 9 and 0 <= j + dj < 7:
                        out[i, j] = g[i + di, j + dj]
            expected.append(out)
        for g, fill in zip(grids, fills, strict=True):
            _shift(g, di, dj, fill)
        for got, want in zip(grids, expected, strict=True):
            np.testing.assert_array_equal(got, want, err_msg=str((di, dj)))
