"""World generation's fast paths give the same terrain, bit for bit, as the plain array
evaluation they replace (issue 21: no flight outcome may change)."""

from __future__ import annotations

import numpy as np
import pytest

import sitl.terrain.features as features
import sitl.terrain.mars as mars
import sitl.terrain.rubble as rubble
from sitl.terrain import make_terrain
from sitl.terrain.terrace_kernel import add_terrace, terrace_heights


def _terrace_by_arrays(patch, xs, ys, cx, cy, theta, steep, gentle, depth, length, height):
    """The terrace as the Mars generator added it before the kernel: every cell through
    numpy's tanh."""
    patch += terrace_heights(xs[None, :] - cx, ys[:, None] - cy, np.cos(theta), np.sin(theta),
                             steep, gentle, depth, length / 2, height)


def _bits(terrain) -> np.ndarray:
    return terrain.grid.view(np.uint32)


@pytest.mark.parametrize("world, seeds", [
    ({"kind": "mars", "size": (200.0, 160.0), "cell_size": 0.2}, range(5)),
    # steep, high faces: the terraces' exponents leave the separable range
    ({"kind": "mars", "size": (200.0, 200.0), "cell_size": 0.25, "scarp_count": 6,
      "scarp_height": (0.5, 40.0), "scarp_slope_deg": (60.0, 89.0)}, range(2)),
    ({"kind": "mars", "size": (400.0, 400.0), "cell_size": 0.2}, [11]),  # mars_science
])
def test_mars_terraces_are_the_array_evaluation_bit_for_bit(world, seeds, monkeypatch):
    fast = [make_terrain(world, seed=s) for s in seeds]
    monkeypatch.setattr(mars, "add_terrace", _terrace_by_arrays)
    for seed, terrain in zip(seeds, fast, strict=True):
        assert np.array_equal(_bits(terrain), _bits(make_terrain(world, seed=seed))), seed


def test_terrace_kernel_handles_overflowing_faces_exactly():
    """A face 1 cm wide over a 100 m patch: exponents of several thousand, cells where the
    smoothsteps saturate to exactly 0 and 1, and heights on both sides of zero."""
    rng = np.random.default_rng(5)
    xs = np.arange(-50.0, 50.0, 0.3)
    ys = np.arange(-40.0, 45.0, 0.3)
    ground = rng.normal(0.0, 1.0, (len(ys), len(xs))).astype(np.float32)
    ground[::7, ::5] = 0.0
    for steep, gentle in [(0.01, 0.5), (3.0, 20.0), (1e-4, 1e-3)]:
        fast, slow = ground.copy(), ground.copy()
        args = (1.5, -2.0, 0.7, steep, gentle, 30.0, 70.0, 9.0)
        add_terrace(fast, xs, ys, *args)
        _terrace_by_arrays(slow, xs, ys, *args)
        assert np.array_equal(fast.view(np.uint32), slow.view(np.uint32)), (steep, gentle)
        assert not np.array_equal(fast, ground)


def _upsample_by_arrays(coarse, factor, shape):
    """Bilinear upsampling as the relief did it before the kernel: one axis at a time with
    whole-array temporaries."""
    out = coarse
    for axis, n in enumerate(shape):
        pos = np.arange(n, dtype=np.float64) / factor
        i0 = np.minimum(pos.astype(np.intp), coarse.shape[axis] - 2)
        w = (pos - i0).astype(np.float32)
        a = np.take(out, i0, axis=axis)
        b = np.take(out, i0 + 1, axis=axis)
        w = w[:, None] if axis == 0 else w[None, :]
        out = a + w * (b - a)
    return np.ascontiguousarray(out, dtype=np.float32)


@pytest.mark.parametrize("world, seeds", [
    ({"kind": "mars", "size": (200.0, 160.0), "cell_size": 0.2}, range(3)),  # 0.5 m relief
    ({"kind": "rubble", "size": (120.0, 100.0), "cell_size": 0.1}, range(2)),  # 1 m piles
    ({"kind": "rubble", "size": (150.0, 130.0), "cell_size": 0.3}, range(2)),  # 0.9 m
])
def test_coarse_reliefs_upsample_as_the_array_evaluation_bit_for_bit(world, seeds,
                                                                      monkeypatch):
    fast = [make_terrain(world, seed=s) for s in seeds]
    monkeypatch.setattr(features, "_upsample", _upsample_by_arrays)
    for seed, terrain in zip(seeds, fast, strict=True):
        assert np.array_equal(_bits(terrain), _bits(make_terrain(world, seed=seed))), seed


def test_upsampling_kernel_matches_the_array_evaluation_on_odd_shapes():
    rng = np.random.default_rng(2)
    for factor, shape in [(2, (7, 9)), (3, (20, 31)), (5, (101, 64)), (10, (33, 250))]:
        small = tuple((n - 1 + factor - 1) // factor + 1 for n in shape)
        coarse = rng.normal(0.0, 3.0, small).astype(np.float32)
        fine = features._upsample(coarse, factor, shape)
        assert fine.shape == shape and fine.dtype == np.float32
        assert np.array_equal(fine.view(np.uint32),
                              _upsample_by_arrays(coarse, factor, shape).view(np.uint32))


def test_fractal_relief_is_the_same_with_its_spectrum_kept_between_worlds():
    """The seed-independent amplitudes are kept for the next world: the surface of a seed is
    the same whether they were computed for it or kept, and nobody can alter them."""
    args = ((90, 70), 0.25, 1.5, 40.0, 3.2)
    features._spectral_amplitude.cache_clear()
    first = features.fractal_relief(*args, np.random.default_rng(4))
    other = features.fractal_relief(*args, np.random.default_rng(5))
    again = features.fractal_relief(*args, np.random.default_rng(4))
    assert features._spectral_amplitude.cache_info().hits == 2
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    with pytest.raises(ValueError):
        features._spectral_amplitude(96, 36, 0.25, 40.0, 3.2)[0, 0] = 1.0


# The array profiles the compiled stamps replace, stamped by features.stamp.
def _ellipses_by_arrays(layer, origin, cs, centers, cos, sin, a, b, height):
    def profile(dx, dy, index):
        c = cos[index, None, None]
        s = sin[index, None, None]
        u = (c * dx + s * dy) / a[index, None, None]
        v = (-s * dx + c * dy) / b[index, None, None]
        q = 1.0 - u * u - v * v
        return np.where(q > 0, height[index, None, None] * np.sqrt(np.maximum(q, 0)), np.nan)

    features.stamp(layer, origin, cs, centers, a, profile, combine=np.maximum)


def _mounds_by_arrays(layer, origin, cs, centers, radius, height):
    def mound(dx, dy, index):
        q = 1.0 - (dx * dx + dy * dy) / radius[index, None, None] ** 2
        return np.where(q > 0, height[index, None, None] * q * q, np.nan)

    features.stamp(layer, origin, cs, centers, radius, mound, combine=np.maximum)


def _boxes_by_arrays(layer, origin, cs, centers, reach, cos, sin, length, width, top):
    def box(dx, dy, index):
        c = cos[index, None, None]
        s = sin[index, None, None]
        inside = (np.abs(c * dx + s * dy) <= length[index, None, None]) & (
            np.abs(-s * dx + c * dy) <= width[index, None, None])
        return np.where(inside, top[index, None, None], np.nan)

    features.stamp(layer, origin, cs, centers, reach, box, combine=np.maximum)


@pytest.mark.parametrize("world, seeds", [
    ({"kind": "mars", "size": (200.0, 160.0), "cell_size": 0.2}, range(3)),
    ({"kind": "mars", "size": (120.0, 100.0), "cell_size": 0.1, "rock_density": 0.2,
      "rock_diameter": (0.2, 3.0)}, range(2)),
    ({"kind": "rubble", "size": (160.0, 120.0), "cell_size": 0.2}, range(3)),
    ({"kind": "rubble", "size": (100.0, 100.0), "cell_size": 0.35}, range(2)),
])
def test_compiled_stamps_are_the_array_profiles_bit_for_bit(world, seeds, monkeypatch):
    fast = [make_terrain(world, seed=s) for s in seeds]
    monkeypatch.setattr(mars, "stamp_ellipses", _ellipses_by_arrays)
    monkeypatch.setattr(rubble, "stamp_mounds", _mounds_by_arrays)
    monkeypatch.setattr(rubble, "stamp_boxes_flat", _boxes_by_arrays)
    for seed, terrain in zip(seeds, fast, strict=True):
        assert np.array_equal(_bits(terrain), _bits(make_terrain(world, seed=seed))), seed


def _craters_by_arrays(layer, origin, cs, centers, radius, depth, rim, tail, reach, profile):
    features.stamp(layer, origin, cs, centers, reach * radius, profile, combine=np.add)


@pytest.mark.parametrize("world, seeds", [
    ({"kind": "mars", "size": (200.0, 160.0), "cell_size": 0.2}, range(3)),
    # saturated ground: craters over craters, added in the stamping order
    ({"kind": "mars", "size": (150.0, 150.0), "cell_size": 0.25, "crater_density": 3000.0,
      "crater_diameter": (2.0, 60.0), "scarp_count": 0}, range(2)),
    ({"kind": "mars", "size": (60.0, 60.0), "cell_size": 0.05, "crater_density": 2000.0,
      "crater_diameter": (0.5, 8.0), "scarp_count": 0, "rock_density": 0.0}, range(2)),
])
def test_crater_kernel_is_the_array_profile_bit_for_bit(world, seeds, monkeypatch):
    fast = [make_terrain(world, seed=s) for s in seeds]
    monkeypatch.setattr(mars, "add_craters", _craters_by_arrays)
    for seed, terrain in zip(seeds, fast, strict=True):
        assert np.array_equal(_bits(terrain), _bits(make_terrain(world, seed=seed))), seed
