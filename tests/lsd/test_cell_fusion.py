"""The order statistic behind each cell's top (lsd.elevation.cell_fusion) against a sort."""

from __future__ import annotations

import numpy as np

from lsd.elevation.cell_fusion import TOP_QUANTILE, _kth_smallest


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

