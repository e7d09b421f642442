"""The order statistic behind each cell's top (lsd.elevation.cell_fusion) against a sort, and
the in-place shift of a recentred map's grids (lsd.elevation.map) against a copy."""

from __future__ import annotations

import numpy as np

from lsd.elevation.cell_fusion import TOP_QUANTILE, _kth_smallest
from lsd.elevation.map import _shift


def test_kth_smallest_is_the_sorted_value_with_ties_and_past_the_network():
    rng = np.random.default_rng(11)
    for m in list(range(1, 90)) + [200, 1000]:
        for ties in (True, False):
            values = rng.normal(-2.5, 3.0, m + 7).astype(np.float32)
            if ties:
                values = np.round(values).astype(np.float32)
            a, b = 3, 3 + m
            ks = {int(TOP_QUANTILE * (m - 1)), 0, m - 1, int(rng.integers(m))}
            for k in ks:
                expected = np.sort(values[a:b])[k]
                got = _kth_smallest(values.copy(), a, b, k)
                assert got == expected, (m, k)


def test_a_cells_top_level_is_the_level_of_its_top_height():
    # The fusion picks the order statistic among the heights and quantises that one: the
    # same level as the order statistic of every point's level (single precision).
    rng = np.random.default_rng(12)
    for n in (2, 7, 30, 300):
        z = (rng.normal(0.0, 1.0, n) * 10.0 ** rng.uniform(-4, 2)).astype(np.float32)
        low, quantum = z.min(), (float(z.max()) - float(z.min()) + 1e-9) / 2.0**50
        inv = np.float32(1.0 / quantum)
        levels = np.minimum(((z - low) * inv).astype(np.int64), (1 << 50) - 1)
        k = int(TOP_QUANTILE * (n - 1))
        top = np.float32(_kth_smallest(z.copy(), 0, n, k))
        assert min(np.int64((top - low) * inv), (1 << 50) - 1) == np.sort(levels)[k]


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
