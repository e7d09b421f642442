"""The compiled back-projection (lsd.elevation.projection) against numpy's single-precision
expressions it replaces, bit for bit."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from lsd.elevation.projection import back_project


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
