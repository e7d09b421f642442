"""The compiled back-projection and median (lsd.elevation.projection) against the numpy
expressions they replace, bit for bit."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from lsd.elevation.projection import back_project, median32


def test_back_projection_is_numpys_single_precision_arithmetic_bit_for_bit():
    f32 = np.float32
    rng = np.random.default_rng(13)
    height, width = 48, 64
    depth = rng.uniform(2.0, 30.0, (height, width)).astype(f32)
    depth[3, 4] = np.nan  # bad pixels pass through (they are dropped afterwards)
    placement = (depth + rng.normal(0.0, 0.1, depth.shape)).astype(f32)
    sigma = rng.uniform(0.01, 0.3, depth.shape).astype(f32)
    rotation = Rotation.from_euler("xyz", [178.0, 4.0, 33.0], degrees=True).as_matrix()
    xn = ((np.arange(width) - 31.5) / 40.0).astype(f32)
    yn = ((np.arange(height) - 23.5) / 40.0).astype(f32)
    min_var = f32(1e-4)
    with np.errstate(invalid="ignore"):
        ray = [f32(r[0]) * xn[None, :] + (f32(r[1]) * yn[:, None] + f32(r[2])) for r in rotation]
        east, north, drop = placement * ray[0], placement * ray[1], depth * ray[2]
        along_axis = east * f32(rotation[0, 2])
        along_axis += north * f32(rotation[1, 2])
        along_axis += drop * f32(rotation[2, 2])
        variance = sigma * np.abs(drop)
        variance /= along_axis
        np.square(variance, out=variance)
        variance += min_var
    got = back_project(depth, placement, sigma, rotation, xn, yn, min_var)
    for a, b in zip(got, (east, north, drop, variance), strict=True):
        assert a.dtype == np.float32 and np.array_equal(a, b, equal_nan=True)
    # Without a per-pixel error every variance is the floor.
    flat = back_project(depth, placement, np.zeros((0, 0), f32), rotation, xn, yn, min_var)
    assert (flat[3] == min_var).all() and np.array_equal(flat[2], drop, equal_nan=True)


def test_median32_is_numpys_median_of_single_precision_values():
    rng = np.random.default_rng(19)
    for n in list(range(1, 40)) + [4095, 4096]:
        values = (rng.normal(-2.5, 1.0, n) * 10.0 ** rng.uniform(-3, 3)).astype(np.float32)
        if n % 3 == 0:
            values = np.round(values, 1).astype(np.float32)  # ties
        got = median32(values.copy())
        assert got == float(np.median(values)), n  # (numba returns the float32 as a float)
    values[7] = np.nan
    assert np.isnan(median32(values)) and np.isnan(np.median(values))

