"""Synthetic classified aerial LiDAR scenes (ASPRS classes) for tests and benchmarks, where
real classified tiles of a land-cover type are not at hand: ``urban`` (ground, flat and
pitched roofs, trees, cars, noise), ``farmland`` (undulating fields, crop strips, hedges)
and ``forest`` (canopy over most of the ground, a few clearings). Seeded, metres.
"""

from __future__ import annotations

import numpy as np

GROUND, LOW_VEG, MEDIUM_VEG, HIGH_VEG, BUILDING, NOISE, UNCLASSIFIED = 2, 3, 4, 5, 6, 7, 1


def scene(kind: str, size: float = 60.0, density: float = 16.0,
          seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(points (N, 3), classes (N,)) of a ``size`` x ``size`` m scene with ``density``
    first returns per m^2 (ground under canopy gets a quarter of them)."""
    rng = np.random.default_rng(seed)
    n = int(size * size * density)
    xy = rng.uniform(0.0, size, (n, 2))
    # Gentle relief: a tilt and a long wave (well under 15 deg).
    z = 0.03 * xy[:, 0] + 0.4 * np.sin(xy[:, 1] / 9.0) + rng.normal(0, 0.015, n)
    cls = np.full(n, GROUND)
    if kind == "urban":
        z, cls = _urban(xy, z, cls, size, rng)
    elif kind == "farmland":
        z, cls = _farmland(xy, z, cls, size, rng)
    elif kind == "forest":
        z, cls = _forest(xy, z, cls, size, rng)
    elif kind != "bare":
        raise ValueError(f"unknown scene kind {kind!r} (urban, farmland, forest, bare)")
    # Under canopy only some pulses reach the ground: thin those ground returns.
    return np.column_stack((xy, z)), cls


def _urban(xy, z, cls, size, rng):
    n_buildings = max(1, int(size * size / 500))
    for _ in range(n_buildings):
        cx, cy = rng.uniform(5, size - 5, 2)
        hx, hy = rng.uniform(3, 7, 2)
        height = rng.uniform(3, 9)
        inside = (np.abs(xy[:, 0] - cx) < hx) & (np.abs(xy[:, 1] - cy) < hy)
        base = z[inside].min() if inside.any() else 0.0
        if rng.random() < 0.5:  # flat roof
            roof = np.full(inside.sum(), base + height)
        else:  # pitched roof along x, 30 deg
            roof = base + height + np.tan(np.radians(30)) * (hy - np.abs(xy[inside, 1] - cy))
        z[inside] = roof + rng.normal(0, 0.015, inside.sum())
        cls[inside] = BUILDING
    for _ in range(int(size * size / 150)):  # trees
        _tree(xy, z, cls, rng.uniform(0, size, 2), rng.uniform(1.5, 3.5), rng.uniform(5, 14),
              rng)
    for _ in range(int(size * size / 400)):  # cars: 2 x 4.5 m, 1.5 m high, unclassified
        cx, cy = rng.uniform(0, size, 2)
        car = (np.abs(xy[:, 0] - cx) < 1.0) & (np.abs(xy[:, 1] - cy) < 2.25) & (cls == GROUND)
        z[car] += 1.5
        cls[car] = UNCLASSIFIED
    noise = rng.random(len(z)) < 0.001
    z[noise] += rng.uniform(-5, 30, noise.sum())
    cls[noise] = NOISE
    return z, cls


def _farmland(xy, z, cls, size, rng):
    # Crop strips of 6 m every 12 m (low vegetation 0.2 - 0.8 m), a hedge along one edge.
    crop = (np.floor(xy[:, 0] / 6.0) % 2 == 1)
    z[crop] += rng.uniform(0.2, 0.8, crop.sum())
    cls[crop] = LOW_VEG
    hedge = np.abs(xy[:, 1] - size * 0.8) < 1.2
    z[hedge] += rng.uniform(1.0, 3.0, hedge.sum())
    cls[hedge] = MEDIUM_VEG
    for _ in range(int(size * size / 900)):
        _tree(xy, z, cls, rng.uniform(0, size, 2), rng.uniform(2, 4), rng.uniform(6, 15), rng)
    return z, cls


def _forest(xy, z, cls, size, rng):
    # Crowns on a jittered grid cover most of the ground; two clearings stay open.
    spacing = 4.0
    g = np.arange(spacing / 2, size, spacing)
    centres = np.stack(np.meshgrid(g, g), -1).reshape(-1, 2)
    centres += rng.uniform(-1, 1, centres.shape)
    clearings = rng.uniform(10, size - 10, (2, 2))
    open_ = (np.hypot(*(centres[:, None, :] - clearings[None]).transpose(2, 0, 1)) < 6).any(1)
    for c in centres[~open_]:
        _tree(xy, z, cls, c, rng.uniform(2.0, 3.2), rng.uniform(12, 25), rng)
    return z, cls


def _tree(xy, z, cls, centre, radius, height, rng):
    """A crown: returns within ``radius`` hit the canopy (high vegetation) three times in
    four; the rest reach the ground below (still ground, under the tree)."""
    r = np.hypot(xy[:, 0] - centre[0], xy[:, 1] - centre[1])
    under = (r < radius) & (cls == GROUND)
    hit = under & (rng.random(len(r)) < 0.75)
    dome = height - 3.0 * (r[hit] / radius) ** 2
    z[hit] += dome + rng.normal(0, 0.3, hit.sum())
    cls[hit] = HIGH_VEG


__all__ = ["scene"]
