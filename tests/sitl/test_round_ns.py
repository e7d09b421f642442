"""The simulator's clock rounding (sitl.copter.simulator.round_ns) is round(t, 9) bit for
bit: on sums of ticks of the usual lengths and on arbitrary doubles, halfway cases and
non-finite values included."""

from __future__ import annotations

import math
import struct

import numpy as np

from sitl.copter.simulator import round_ns


def _bits(x: float) -> bytes:
    return struct.pack("<d", x)


def test_round_ns_is_round_to_nine_digits():
    rng = np.random.default_rng(5)
    values = []
    for h in (0.05, 0.025, 0.1 / 3, 0.02, 1 / 30, 0.0125, 0.1):
        t = 0.0
        for i in range(4000):  # the simulator's sums: t0 + i * h, rounded, step by step
            t = round(t + h, 9) if i % 3 else round(t + 2 * h, 9)
            values.append(t + h)
    values += rng.uniform(-1e4, 1e6, 20000).tolist()
    values += (rng.integers(0, 10**12, 20000) / 1e9 + 5e-10).tolist()  # halfway-ish
    values += (rng.integers(0, 10**6, 2000) * 0.0000000005).tolist()
    values += [0.0, -0.0, 1e-12, -1e-12, 4.9999999999e-10, 5e-10, 1e6 + 5e-10, 1e7, 1e20,
               -1e20, math.inf, -math.inf, math.nan]
    for t in values:
        assert _bits(round_ns(t)) == _bits(round(t, 9)), t
