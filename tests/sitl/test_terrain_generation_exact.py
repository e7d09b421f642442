"""World generation's fast paths give the same terrain, bit for bit, as the plain array
evaluation they replace (issue 21: no flight outcome may change)."""

from __future__ import annotations

import numpy as np
import pytest

import sitl.terrain.mars as mars
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
