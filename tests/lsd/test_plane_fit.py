"""The window plane fits (lsd.plane_fit, compiled in lsd.plane_fit_kernel) against oracles:
a weighted least-squares fit of each window by numpy, and OpenCV's box filter, whose sums
the kernel reproduces bit for bit."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from lsd.plane_fit import fit_planes


def _map(shape, seed):
    rng = np.random.default_rng(seed)
    i, j = np.mgrid[0 : shape[0], 0 : shape[1]] * 0.1
    height = 3.0 + 0.2 * i - 0.1 * j + rng.normal(0.0, 0.02, shape)
    variance = rng.uniform(1e-4, 4e-4, shape)
    height[rng.random(shape) < 0.3] = np.nan  # unobserved cells
    variance[np.isnan(height)] = np.inf
    return height, variance


@pytest.mark.parametrize("shape", [(40, 37), (33, 44)])
def test_plane_is_the_weighted_least_squares_fit_of_each_window(shape):
    height, variance = _map(shape, 1)
    fit = fit_planes(height, variance, 0.1, 0.3)  # 7 x 7 windows
    rng = np.random.default_rng(2)
    for i, j in zip(rng.integers(0, shape[0], 40), rng.integers(0, shape[1], 40), strict=True):
        win = tuple(slice(max(k - 3, 0), min(k + 4, n)) for k, n in zip((i, j), shape, strict=True))
        di, dj = np.mgrid[win]
        seen = np.isfinite(height[win])
        w = np.sqrt(1.0 / variance[win][seen])
        a = np.column_stack([np.ones(seen.sum()), (di[seen] - i) * 0.1, (dj[seen] - j) * 0.1])
        coef = np.linalg.lstsq(a * w[:, None], height[win][seen] * w, rcond=None)[0]
        assert fit.height[i, j] == pytest.approx(coef[0], abs=1e-4)
        assert fit.slope[i, j] == pytest.approx(np.arctan(np.hypot(coef[1], coef[2])), abs=1e-3)
        assert fit.observed_fraction[i, j] == pytest.approx(seen.sum() / 49, abs=1e-6)


@pytest.mark.parametrize(("shape", "radius"), [((41, 38), 1.0), ((30, 29), 0.2), ((25, 27), 0.1)])
def test_window_sums_are_opencvs_box_filter_bit_for_bit(shape, radius):
    height, variance = _map(shape, 3)
    fit = fit_planes(height, variance, 0.1, radius)
    size = 2 * max(1, round(radius / 0.1)) + 1
    seen = np.isfinite(height)
    var = np.where(seen, variance, 0.0).astype(np.float32)

    def box(a):
        return cv2.boxFilter(a, cv2.CV_32F, (size, size), borderType=cv2.BORDER_CONSTANT)

    frac = box(seen.astype(np.uint8))
    # The mask's scaling rounds as OpenCV's four-lane loop and scalar tail do on this build;
    # another build or CPU may vector it differently, so only to the last bit here
    # (tests/speed pins it bit for bit where the recordings were made).
    assert np.allclose(fit.observed_fraction, np.clip(frac, 0, 1), rtol=2e-7, atol=0)
    expected_sigma = np.sqrt(box(var) / frac)
    ok = np.isfinite(fit.sigma)
    assert ok.sum() > 0.5 * ok.size
    assert np.array_equal(fit.sigma[ok], expected_sigma[ok])


def test_safe_mask_tests_the_slope_of_every_cell_the_other_limits_pass():
    from lsd.elevation.settings import DetectorSettings
    from lsd.site_selection import safe_mask

    height, variance = _map((60, 50), 5)
    height += np.random.default_rng(6).normal(0.0, 0.03, height.shape)  # some rough windows
    fit = fit_planes(height, variance, 0.1, 0.5)
    settings = DetectorSettings(max_slope=13.0, max_roughness=0.03, noise_tolerance=1.0)
    hazard = np.zeros(height.shape, bool)
    hazard[10:20, 10:30] = True
    safe = safe_mask(fit, settings, hazard)
    k = settings.noise_tolerance
    with np.errstate(invalid="ignore"):
        rest = (
            (fit.observed_fraction >= settings.min_observed_fraction)
            & (fit.roughness**2 - k * fit.roughness_error <= settings.max_roughness**2)
            & (fit.sigma <= settings.max_uncertainty)
            & ~hazard
        )
        gentle = np.arctan(fit.gradient) - k * fit.slope_error <= settings.max_slope_rad
    rest[[0, -1], :] = rest[:, [0, -1]] = False
    # The slope limit alone rules out many cells that pass every other test.
    assert (rest & gentle).sum() > 50 and (rest & ~gentle).sum() > 50
    assert np.array_equal(safe, rest & gentle)
    assert np.array_equal(fit.slope, np.arctan(fit.gradient), equal_nan=True)


def test_reference_height_is_numpys_median_of_the_finite_subsample():
    from lsd.plane_fit_kernel import reference_height

    rng = np.random.default_rng(9)
    for shape, stride, hidden in [((64, 61), 3, 0.4), ((20, 9), 2, 0.0), ((9, 9), 4, 0.97)]:
        height = np.round(rng.normal(5.0, 2.0, shape), 1)  # ties among the middle values
        height[rng.random(shape) < hidden] = np.nan
        sample = height[::stride, ::stride]
        sample = sample[np.isfinite(sample)]
        if len(sample) == 0:
            sample = height[np.isfinite(height)]
        assert reference_height(height, stride) == np.median(sample)
    assert reference_height(np.full((4, 4), np.nan), 2) == 0.0


def test_the_same_map_gives_the_same_fits_wherever_its_arrays_lie():
    """Flights are compared bit for bit: a fit must not depend on the memory addresses of
    its arrays (OpenCV's vectorised gradient magnitude rounded some cells by alignment)."""
    rng = np.random.default_rng(3)
    height = rng.normal(5.0, 1.0, (97, 131)).cumsum(axis=0) * 0.01 + 100.0
    variance = rng.uniform(0.001, 0.1, height.shape)
    height[rng.random(height.shape) < 0.3] = np.nan
    variance[np.isnan(height)] = np.inf
    first = fit_planes(height, variance, 0.25, 1.0, top=height, tolerance=3.0)
    kept = []
    for size in rng.integers(1, 5000, 60):
        kept.append(np.empty(size))  # the next arrays land elsewhere
        fit = fit_planes(height, variance, 0.25, 1.0, top=height, tolerance=3.0)
        for name in ("gradient", "slope_error", "height", "roughness", "step"):
            assert getattr(fit, name).tobytes() == getattr(first, name).tobytes(), name
