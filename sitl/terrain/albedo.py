"""What a world looks like to a greyscale camera: a per-cell albedo (reflectance) matching its
features, Lambertian shading from the height grid's normals, and a seeded multi-scale grain
below the cell size, so that image-based methods (the optical-flow descent watch of seed 004)
find corners to track at any altitude.

The features are read back from the height grid alone, as a surveyor reads a DEM:

* the *local ground* (a grey opening of the grid: everything narrower than the window is
  taken off) gives each cell its height above the ground;
* raised cells are grouped into connected objects; an object that is mostly level on top
  is a roof, a car, a slab or a block, one that is curved all over is a tree crown, a rock
  or a debris pile (by world kind);
* at ground level the kind decides: road and kerbed pavement (grass or paving by a seeded
  patch field) in ``urban``, regolith with darker dust-free patches, bright crater floors
  and layered scarp faces on ``mars``, concrete dust in ``rubble``, soil and grass patches
  on ``flat`` and ``file`` worlds.

Each object gets its own albedo drawn from its class's range, each class its own grain
contrast. :meth:`AlbedoMap.radiance` returns albedo x shading at any ENU points, the grain
band-limited to the pixel footprint (octaves finer than two pixels fade out, so a frame
from high up does not alias and one from 3 m still has pixel-scale corners).

Randomness comes from the ``numpy.random.Generator`` passed in (the flight derives it from
the mission seed); nothing here touches the terrain's own generator.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage

from sitl.terrain.grid import Terrain

# Grain octaves: wavelengths from 1.5 cm (a 3 m look with f = 160 px has 1.9 cm pixels)
# up to several metres, each a bilinear lookup into its own table of uniform noise.
_OCTAVES = 0.015 * 2.1 ** np.arange(10)
_TABLE = 256
# Grey-opening window (m) that takes each kind's raised features off its ground.
_GROUND_WINDOW = {"mars": 4.0, "urban": 34.0, "rubble": 34.0, "flat": 4.0, "file": 34.0}
_LEVEL_SLOPE = np.tan(np.radians(12.0))  # flatter than this: level on top


@dataclass(frozen=True)
class Sun:
    """Sun direction and sky light.

    Attributes:
        azimuth: degrees clockwise from north (YAML convention, like wind direction).
        elevation: degrees above the horizon.
        ambient: share of the light that reaches every surface (sky), 0..1.
    """

    azimuth: float = 135.0
    elevation: float = 50.0
    ambient: float = 0.35

    def vector(self) -> np.ndarray:
        """(3,) unit vector towards the sun, ENU."""
        az, el = np.radians(self.azimuth), np.radians(self.elevation)
        return np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])


class AlbedoMap:
    """A world's shaded albedo and grain (see the module's docstring).

    Args:
        terrain: the world (its ``kind`` chooses the feature classes).
        rng: draws object albedos, patch fields and the grain tables.
        sun: the light; default :class:`Sun`.

    Attributes:
        albedo: (ny, nx) float32 reflectance of each cell, 0..1.
        grain: (ny, nx) float32 relative contrast of the sub-cell grain, 0..1.
        shading: (ny, nx) float32 Lambertian light on each cell, ambient..1.
    """

    def __init__(self, terrain: Terrain, rng: np.random.Generator, sun: Sun | None = None):
        self.terrain = terrain
        self.sun = sun or Sun()
        cs = terrain.cell_size
        grid = terrain.grid
        kind = terrain.kind if terrain.kind in _GROUND_WINDOW else "file"
        ground = local_ground(grid, cs, _GROUND_WINDOW[kind])
        gy, gx = np.gradient(grid, cs)
        slope = np.hypot(gx, gy)
        albedo, grain = _CLASSIFIERS[kind](grid, ground, slope, cs, rng)
        self.albedo = np.clip(albedo, 0.02, 0.95).astype(np.float32)
        self.grain = np.clip(grain, 0.0, 1.0).astype(np.float32)
        s = self.sun.vector()
        lambert = np.maximum((-gx * s[0] - gy * s[1] + s[2]) / np.sqrt(1 + gx**2 + gy**2), 0)
        a = self.sun.ambient
        self.shading = (a + (1 - a) * lambert).astype(np.float32)
        # Sampled like the terrain itself: bilinear between cell centres, edge values
        # beyond the grid (OpenCV's remap of both channels at once).
        self._cells = np.ascontiguousarray(np.dstack([self.albedo * self.shading, self.grain]))
        self._tables = (rng.random((len(_OCTAVES), _TABLE, _TABLE), dtype=np.float32) * 2 - 1)
        angles = rng.uniform(0, 2 * np.pi, len(_OCTAVES))
        self._rotation = np.stack([np.cos(angles), np.sin(angles)], axis=1)
        self._offset = rng.uniform(0, _TABLE, (len(_OCTAVES), 2))

    def texture(self, x, y, z, footprint) -> np.ndarray:
        """Zero-mean grain at ENU points (about -1..1, float32), band-limited to
        ``footprint`` (m per pixel at each point): octaves whose wavelength is under two
        footprints are left out, between two and four they fade in. Height shears the
        lookup so that walls seen at a slant are textured too."""
        x = np.asarray(x, dtype=np.float64)
        u0 = x + 0.6 * np.asarray(z)
        v0 = np.asarray(y, dtype=np.float64) + 0.8 * np.asarray(z)
        ratio = np.asarray(footprint, dtype=np.float64)
        total = np.zeros(np.broadcast_shapes(u0.shape, ratio.shape), dtype=np.float32)
        weight_sq = np.zeros_like(total)
        finest = float(np.nanmin(ratio)) if ratio.size else 0.0
        for k, wavelength in enumerate(_OCTAVES):
            if wavelength < 2.0 * finest:
                continue  # under two pixels everywhere in this frame
            w = np.clip(wavelength / ratio / 2.0 - 1.0, 0.0, 1.0).astype(np.float32)
            c, s = self._rotation[k]
            u = (c * u0 - s * v0) / wavelength + self._offset[k, 0]
            v = (s * u0 + c * v0) / wavelength + self._offset[k, 1]
            total += w * _lookup(self._tables[k], u, v)
            weight_sq += w * w
        return total / np.sqrt(np.maximum(weight_sq, 1e-6))

    def radiance(self, x, y, z, footprint) -> np.ndarray:
        """Albedo x shading x (1 + grain contrast x texture) at ENU points, float32 >= 0."""
        x0, y0 = self.terrain.origin
        cs = self.terrain.cell_size
        fx = (np.asarray(x, dtype=np.float64) - x0) / cs
        fy = (np.asarray(y, dtype=np.float64) - y0) / cs
        both = _remap(self._cells, fx, fy, cv2.BORDER_REPLICATE)
        base, contrast = both[..., 0], both[..., 1]
        return np.maximum(base * (1.0 + contrast * self.texture(x, y, z, footprint)), 0.0)


def _remap(image: np.ndarray, u: np.ndarray, v: np.ndarray, border: int) -> np.ndarray:
    """Bilinear samples of ``image`` (rows, columns[, channels]) at fractional (column, row)
    indices ``u``, ``v`` of any shape (OpenCV's remap; its fixed-point maps hold 15 bits, so
    indices are clipped to the image, which ``BORDER_REPLICATE`` does anyway)."""
    shape = np.shape(u)
    size = int(np.prod(shape))
    width = 1024
    rows = -(-size // width)
    if rows == 0:
        return np.zeros(shape + image.shape[2:], dtype=np.float32)
    maps = []
    for t, n in ((u, image.shape[1]), (v, image.shape[0])):
        flat = np.zeros(rows * width, dtype=np.float32)
        flat[:size] = np.clip(np.ravel(t), -1.0, n)
        flat[np.isnan(flat)] = 0.0  # no point: any value, the caller masks it
        maps.append(flat.reshape(rows, width))
    out = cv2.remap(image, maps[0], maps[1], cv2.INTER_LINEAR, borderMode=border)
    return out.reshape((rows * width,) + image.shape[2:])[:size].reshape(shape + image.shape[2:])


def _lookup(table: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Bilinear lookup into a periodic square table at fractional indices."""
    n = table.shape[0]
    return _remap(table, np.mod(u, n), np.mod(v, n), cv2.BORDER_WRAP)


def local_ground(grid: np.ndarray, cell_size: float, window: float) -> np.ndarray:
    """The ground under raised features: a grey opening of ``grid`` with a ``window`` m
    square (features narrower than it are taken off), on ~1 m blocks when the window is
    large (a block's minimum: the opening never rises above the ground) and interpolated
    back."""
    block = max(1, int(round(min(1.0, window / 8) / cell_size)))
    ny, nx = grid.shape
    if block > 1:
        py, px = (-ny) % block, (-nx) % block
        padded = np.pad(grid, ((0, py), (0, px)), mode="edge")
        coarse = padded.reshape(padded.shape[0] // block, block, -1, block).min(axis=(1, 3))
    else:
        coarse = grid
    size = max(1, int(round(window / (cell_size * block))))
    opened = ndimage.grey_opening(coarse, size=(size, size), mode="nearest")
    if block == 1:
        return opened
    fine = cv2.resize(opened, (opened.shape[1] * block, opened.shape[0] * block),
                      interpolation=cv2.INTER_LINEAR)
    return np.minimum(fine[:ny, :nx], grid)


def patches(shape: tuple[int, int], cell_size: float, scale: float,
            rng: np.random.Generator) -> np.ndarray:
    """A smooth random field in 0..1 varying over ``scale`` m (cubic upsampling of uniform
    noise on ``scale``-m nodes)."""
    ny, nx = shape
    step = max(scale / cell_size, 1.0)
    coarse = rng.random((int(ny / step) + 2, int(nx / step) + 2), dtype=np.float32)
    big = (int(round(coarse.shape[1] * step)), int(round(coarse.shape[0] * step)))
    field = cv2.resize(coarse, big, interpolation=cv2.INTER_CUBIC)[:ny, :nx]
    lo, hi = np.percentile(coarse, [5, 95]) if coarse.size > 16 else (0.0, 1.0)
    return np.clip((field - lo) / max(hi - lo, 1e-6), 0.0, 1.0)


def _objects(raised: np.ndarray, level: np.ndarray):
    """Connected raised objects: labels (0 = ground) and, per label, whether it is mostly
    level on top (index 0 unused)."""
    labels, count = ndimage.label(raised)
    if count == 0:
        return labels, np.zeros(1, dtype=bool)
    share = ndimage.mean(level, labels, np.arange(1, count + 1))
    return labels, np.concatenate([[False], np.asarray(share) > 0.5])


def _per_object(labels: np.ndarray, lo: float, hi: float, rng: np.random.Generator):
    """A value drawn per object (uniform in lo..hi), spread over its cells."""
    values = rng.uniform(lo, hi, labels.max() + 1)
    return values[labels]


def _mars(grid, ground, slope, cs, rng):
    hag = grid - ground
    shape = grid.shape
    # Regolith: bright dust and darker sand in patches of tens of metres.
    albedo = 0.26 + 0.08 * (patches(shape, cs, 25.0, rng) - 0.5)
    grain = np.full(shape, 0.3, np.float32)
    # Crater floors collect bright dust.
    bowl = grid - ndimage.uniform_filter(grid, size=max(3, int(12.0 / cs)), mode="nearest")
    albedo += 0.05 * np.clip(-bowl / 1.0, 0.0, 1.0)
    # Scarp faces: layered bedrock, banded with height.
    steep = np.clip((slope - 0.45) / 0.3, 0.0, 1.0)
    albedo = albedo * (1 - steep) + steep * (0.2 + 0.06 * np.sin(2 * np.pi * grid / 1.3))
    grain = grain * (1 - steep) + 0.45 * steep
    # Rocks: raised knobs a few square metres across (the relief's own bumps spread wider).
    labels, count = ndimage.label(hag > 0.1)
    area = np.bincount(labels.ravel(), minlength=count + 1) * cs * cs
    small = area < 30.0
    small[0] = False
    labels = np.where(small[labels], labels, 0)
    rock = labels > 0
    albedo = np.where(rock, _per_object(labels, 0.12, 0.22, rng), albedo)
    grain = np.where(rock, 0.5, grain)
    return albedo, grain


def _urban(grid, ground, slope, cs, rng):
    # The town stands on level ground: the road surface is its lowest level, the kerbed
    # pavement 0.15 m above it.
    floor = float(np.percentile(grid, 0.5))
    above = grid - floor
    road = above < 0.07
    shape = grid.shape
    grass = patches(shape, cs, 6.0, rng) > 0.55
    albedo = np.where(road, 0.12, np.where(grass, 0.15, 0.33))
    grain = np.where(road, 0.5, np.where(grass, 0.6, 0.3))
    labels, level = _objects(above > 0.5, slope < _LEVEL_SLOPE)
    top = ndimage.maximum(above, labels, np.arange(labels.max() + 1)) if labels.max() else [0]
    top = np.asarray(top)
    roof = level & (top >= 2.2)
    car = level & (top < 2.2)
    tree = ~level
    tree[0] = roof[0] = car[0] = False
    drawn_roof = _per_object(labels, 0.18, 0.55, rng)
    drawn_car = _per_object(labels, 0.04, 0.75, rng)
    albedo = np.where(roof[labels], drawn_roof, albedo)
    albedo = np.where(car[labels], drawn_car, albedo)
    albedo = np.where(tree[labels], 0.08 + 0.05 * patches(shape, cs, 2.0, rng), albedo)
    grain = np.where(roof[labels], 0.35, grain)
    grain = np.where(car[labels], 0.1, grain)
    grain = np.where(tree[labels], 0.75, grain)
    return albedo, grain


def _rubble(grid, ground, slope, cs, rng):
    hag = grid - ground
    shape = grid.shape
    albedo = 0.36 + 0.1 * (patches(shape, cs, 10.0, rng) - 0.5)
    grain = np.full(shape, 0.4, np.float32)
    labels, level = _objects(hag > 0.3, slope < _LEVEL_SLOPE)
    slab = level[labels] & (labels > 0)
    debris = ~level[labels] & (labels > 0)
    albedo = np.where(slab, _per_object(labels, 0.3, 0.6, rng), albedo)
    albedo = np.where(debris, 0.26 + 0.1 * patches(shape, cs, 1.5, rng), albedo)
    grain = np.where(slab, 0.3, np.where(debris, 0.65, grain))
    return albedo, grain


def _open_ground(grid, ground, slope, cs, rng):
    """Soil and grass in patches; raised level objects are roofs, raised curved ones
    vegetation or rock (``flat`` and ``file`` worlds)."""
    hag = grid - ground
    shape = grid.shape
    mix = patches(shape, cs, 8.0, rng)
    albedo = 0.14 + 0.2 * mix
    grain = 0.35 + 0.25 * (1 - mix)
    labels, level = _objects(hag > 0.5, slope < _LEVEL_SLOPE)
    roof = level[labels] & (labels > 0)
    plant = ~level[labels] & (labels > 0)
    albedo = np.where(roof, _per_object(labels, 0.2, 0.55, rng), albedo)
    albedo = np.where(plant, 0.1, albedo)
    grain = np.where(roof, 0.35, np.where(plant, 0.7, grain))
    return albedo, grain


_CLASSIFIERS = {
    "mars": _mars,
    "urban": _urban,
    "rubble": _rubble,
    "flat": _open_ground,
    "file": _open_ground,
}
