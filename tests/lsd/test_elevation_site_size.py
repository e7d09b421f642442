"""Site sizes and step room from distance transforms: exact and reproducible."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy import ndimage

from lsd.elevation.settings import DetectorSettings
from lsd.plane_fit import PlaneFit
from lsd.site_selection import site_size, step_room


def test_site_size_is_the_exact_distance_and_the_same_on_every_call():
    rng = np.random.default_rng(4)
    safe = rng.random((160, 120)) < 0.97
    resolution = 0.25
    sizes = [site_size(safe, resolution) for _ in range(30)]
    # Equal bit for bit from call to call, so that ties between sites break the same way.
    assert all(np.array_equal(sizes[0], s) for s in sizes[1:])
    exact = np.maximum(ndimage.distance_transform_edt(safe) - 0.5, 0.0) * resolution
    np.testing.assert_allclose(sizes[0], exact, atol=1e-5)


def test_step_room_is_the_distance_to_the_nearest_step_beyond_max_step():
    settings = DetectorSettings(max_step=0.05)
    step = np.full((40, 30), 0.01, dtype=np.float32)
    step[5, 5] = np.nan  # unobserved: no step
    fit = PlaneFit(*(np.zeros_like(step) for _ in range(9)))
    fit = dataclasses.replace(fit, step=step)
    # No cell beyond max_step: unlimited room everywhere, the grid's border included.
    assert np.isinf(step_room(fit, settings, 0.1)).all()
    step[20, 10] = 0.06
    room = step_room(fit, settings, 0.1)
    i, j = np.indices(step.shape)
    exact = np.maximum(np.hypot(i - 20, j - 10) - 0.5, 0.0) * 0.1
    np.testing.assert_allclose(room, exact, atol=1e-5)


def test_site_size_is_scipys_exact_distance_in_whole_squared_cells():
    # Masks from scattered unsafe cells to a lone one, on grids of odd shapes.
    rng = np.random.default_rng(8)
    for shape, share in [((64, 45), 0.5), ((37, 80), 0.05), ((50, 50), 0.002), ((1, 30), 0.2)]:
        safe = rng.random(shape) >= share
        safe.flat[rng.integers(safe.size)] = False
        resolution = 0.1
        # scipy's nearest unsafe cell gives the squared distance as a whole number.
        index = ndimage.distance_transform_edt(safe, return_distances=False, return_indices=True)
        i, j = np.indices(shape)
        squared = (index[0] - i) ** 2 + (index[1] - j) ** 2
        root = np.sqrt(squared.astype(np.float32)).astype(np.float64)
        expected = np.maximum(root - 0.5, 0.0) * resolution
        assert np.array_equal(site_size(safe, resolution), expected)


def test_step_room_at_wanted_cells_is_exact_as_far_as_the_selection_reads_it():
    from lsd.site_selection import room_reach

    settings = DetectorSettings(max_step=0.05, look_margin=0.5, site_spacing=4.0)
    rng = np.random.default_rng(14)
    reach = room_reach(settings, 0.1)
    assert reach == 3.0  # the ranking's cap: footprint 1 m + half a 4 m block
    counts = np.zeros(2, int)
    for share in (0.6, 0.01, 0.0005):  # dense steps to a few
        step = np.where(rng.random((90, 70)) < share, 0.2, 0.0).astype(np.float32)
        step[0, 0] = 0.2
        fit = dataclasses.replace(PlaneFit(*(np.zeros_like(step) for _ in range(9))), step=step)
        wanted = rng.random(step.shape) < 0.5
        full = step_room(fit, settings, 0.1)
        room = step_room(fit, settings, 0.1, wanted)
        near = wanted & (full < reach)
        counts += near.sum(), (wanted & ~near).sum()
        assert np.array_equal(room[near], full[near])
        # Beyond the reach: exact, or inf (either ranks and doubts alike); unwanted: inf.
        far = wanted & ~near
        assert ((room[far] == full[far]) | np.isinf(room[far])).all()
        assert np.isinf(room[~wanted]).all()
    assert (counts > 300).all()  # both within and beyond the reach, many times


def test_step_levels_are_numpys_single_precision_comparisons():
    from lsd.site_selection import step_hazards, step_levels

    settings = DetectorSettings(max_step=0.05, noise_tolerance=3.0, clearance_margin=0.0)
    rng = np.random.default_rng(21)
    limit = np.float32(0.05)
    # Steps at, just above and just below the limit (in float32), random ones, NaN.
    near = np.array([limit, np.nextafter(limit, np.float32(1)),
                     np.nextafter(limit, np.float32(0))], np.float32)
    step = rng.choice(np.concatenate([near, rng.random(5, dtype=np.float32) * 0.2,
                                      [np.nan]]).astype(np.float32), size=(60, 50))
    error = rng.choice(np.array([0.0, 1e-3, 0.01, np.nan], np.float32), size=step.shape)
    fit = dataclasses.replace(PlaneFit(*(np.zeros_like(step) for _ in range(9))), step=step,
                              step_error=error)
    with np.errstate(invalid="ignore"):
        expected = (step > 0.05).astype(np.uint8) + (step - 3.0 * error > 0.05)
    level = step_levels(fit, settings, 0.1)
    assert np.array_equal(level, expected) and set(np.unique(level)) == {0, 1, 2}
    hazard, doubtful = step_hazards(fit, settings, 0.1)
    assert np.array_equal(hazard, expected >= 2) and np.array_equal(doubtful, expected >= 1)


def test_step_room_at_given_cells_is_exact_up_to_each_cells_bound():
    from lsd.site_selection import step_room_at

    settings = DetectorSettings(max_step=0.05)
    rng = np.random.default_rng(23)
    counts = np.zeros(2, int)
    for share in (0.3, 0.01, 0.0005):
        step = np.where(rng.random((80, 90)) < share, 0.2, 0.0).astype(np.float32)
        step[3, 70] = 0.2
        fit = dataclasses.replace(PlaneFit(*(np.zeros_like(step) for _ in range(9))), step=step)
        full = step_room(fit, settings, 0.1)
        i, j = np.nonzero(rng.random(step.shape) < 0.3)
        bound = rng.uniform(0.2, 4.0, len(i))
        room = step_room_at(fit, settings, 0.1, i, j, bound)
        within = full[i, j] <= bound
        counts += within.sum(), (~within).sum()
        assert np.array_equal(room[within], full[i, j][within])
        # Beyond its bound a cell's room is exact or inf: it decides nothing there.
        assert ((room[~within] == full[i, j][~within]) | np.isinf(room[~within])).all()
    assert (counts > 300).all()


def test_obstacle_altitude_at_sites_is_the_largest_top_of_each_square():
    from lsd.site_selection import obstacle_altitude

    rng = np.random.default_rng(24)
    height = rng.normal(0.0, 0.3, (70, 60))
    height[rng.random(height.shape) < 0.2] = np.nan
    variance = rng.uniform(0.0, 0.01, height.shape)
    i, j = rng.integers(0, 70, 40), rng.integers(0, 60, 40)
    got = obstacle_altitude(height, variance, 0.1, 0.5, sites=(i, j))
    f32 = np.float32
    with np.errstate(invalid="ignore"):
        top = ((np.sqrt(variance.astype(f32)) * f32(2)).astype(np.float64) + height).astype(f32)
    top[np.isnan(top)] = -np.inf
    expected = [top[max(a - 5, 0): a + 6, max(b - 5, 0): b + 6].max()
                for a, b in zip(i, j, strict=True)]
    assert np.array_equal(got, np.array(expected, np.float64))
    # Where the largest is a zero of either sign, the first in row-major order stands.
    flat = np.full((20, 20), -1.0)
    variance = np.zeros(flat.shape)
    flat[4, 12], variance[4, 12] = -0.0, -0.0  # -0 + 2 sqrt(-0): a negative zero
    flat[9, 3] = 0.0
    first = obstacle_altitude(flat, variance, 0.1, 1.0, sites=(np.array([8]), np.array([8])))
    assert first[0] == 0 and np.signbit(first[0])


def test_column_distances_in_int16_are_the_int32_ones_and_numpys():
    """Maps take the int16 column pass (grids up to 2048 cells a side); the int32 one stays
    for grids too large for it: both give each cell's distance to the nearest outside cell
    of its column, capped, and the same transforms."""
    from lsd.distance_transform import (
        _column_distances,
        _row_distances,
        _short_column_distances,
        distance_to_outside,
    )

    rng = np.random.default_rng(11)
    for shape, share in [((40, 23), 0.1), ((1, 9), 0.5), ((30, 1), 0.05), ((25, 25), 0.0)]:
        inside = rng.random(shape) >= share
        rows = np.arange(shape[0])[:, None]
        for far in (3, 50):
            expected = np.full(shape, far)
            for j in range(shape[1]):
                outside = np.flatnonzero(~inside[:, j])
                if len(outside):
                    nearest = np.abs(rows[:, 0, None] - outside[None, :]).min(axis=1)
                    expected[:, j] = np.minimum(nearest, far)
            short = _short_column_distances(inside, far)
            assert short.dtype == np.int16 and np.array_equal(short, expected)
            assert np.array_equal(_column_distances(inside, far), expected)
        if not inside.all():
            far = sum(shape)
            assert np.array_equal(_row_distances(_column_distances(inside, far), 0.1),
                                  distance_to_outside(inside, 0.1))
