"""The compiled back-projection, median and pixel blocks (lsd.elevation.projection) against
the numpy and OpenCV expressions they replace, bit for bit."""

from __future__ import annotations

import cv2
import numpy as np
from scipy.spatial.transform import Rotation

from lsd.elevation.projection import back_project, block_points, median32, valid_points


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



def _opencv_block_points(east, north, drop, variance, valid, block):
    """The pixel blocks as the array version made them: block means by OpenCV's
    INTER_AREA resize of the masked images, times the block's area."""
    f32 = np.float32
    rows, cols = valid.shape[0] // block, valid.shape[1] // block
    crop = (slice(0, rows * block), slice(0, cols * block))
    mask = valid[crop]
    weight = np.zeros(mask.shape, f32)
    np.divide(f32(1.0), variance[crop], out=weight, where=mask)

    def total(image):
        mean = cv2.resize(image, (cols, rows), interpolation=cv2.INTER_AREA).reshape(-1)
        return mean * f32(block * block)

    def masked(image):
        return np.where(mask, image[crop], f32(0.0))

    count = total(mask.astype(f32))
    w_sum = total(weight)
    wz_sum = total(weight * masked(drop))
    east_sum, north_sum = total(masked(east)), total(masked(north))
    keep = np.flatnonzero(count > 0.5)
    count, w_sum = count[keep], w_sum[keep]
    return (east_sum[keep] / count, north_sum[keep] / count, wz_sum[keep] / w_sum,
            1.0 / w_sum, np.rint(count))


def test_pixel_blocks_are_opencvs_block_means_bit_for_bit():
    # Values over many orders of magnitude, so that any other order of the sums shows; odd
    # sizes (partial blocks left out; 2 x 2 blocks past the last four of a row summed in
    # OpenCV's scalar order), every pixel valid or a few.
    f32 = np.float32
    rng = np.random.default_rng(23)
    for trial in range(60):
        block = (2, 4, 8)[trial % 3]
        height, width = (int(v) for v in rng.integers(block, 70, 2))
        east, north, drop = (
            (rng.standard_normal((height, width)) * 10.0 ** rng.integers(-2, 4, (height, width)))
            .astype(f32) for _ in range(3)
        )
        variance = (rng.random((height, width)) * 10.0 ** rng.integers(-6, 1, (height, width))
                    + 1e-7).astype(f32)
        valid = rng.random((height, width)) < (0.1, 0.8, 1.0)[trial % 5 % 3]
        got = block_points(east, north, drop, variance, valid, block)
        want = _opencv_block_points(east, north, drop, variance, valid, block)
        for a, b in zip(got, want, strict=True):
            assert a.dtype == b.dtype == np.float32 and a.tobytes() == b.tobytes(), trial


def test_valid_points_are_the_grids_at_the_valid_pixels_in_row_major_order():
    rng = np.random.default_rng(21)
    grids = [rng.normal(0.0, 1.0, (37, 41)).astype(np.float32) for _ in range(4)]
    valid = rng.random((37, 41)) < 0.8
    got = valid_points(valid, *grids, int(np.count_nonzero(valid)))
    pick = np.flatnonzero(valid)
    for a, b in zip(got, grids, strict=True):
        assert a.dtype == np.float32 and np.array_equal(a, b.reshape(-1)[pick])
