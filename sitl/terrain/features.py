"""Building blocks of the procedural worlds: fractal relief, power-law size draws, and
vectorised stamping of many small features (rocks, trees, craters) into a grid."""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
import scipy.fft

from sitl.terrain.bilinear_kernel import upsample_rows_then_columns

# Stamp half-sizes (cells) are rounded up to these levels so that features are stamped in
# few batches; each batch is one vectorised operation.
_LEVELS = np.unique(np.round(1.3 ** np.arange(40)).astype(np.intp))
# Largest batch in grid elements (memory bound of one vectorised stamp).
_BATCH_ELEMENTS = 4_000_000


def fractal_relief(
    shape: tuple[int, int],
    cell_size: float,
    rms: float,
    wavelength: float,
    beta: float,
    rng: np.random.Generator,
    coarsen: int = 1,
) -> np.ndarray:
    """Gaussian random surface by spectral synthesis: power spectrum ~ k^-beta above the
    wavenumber 1/``wavelength`` and flat below it, scaled to ``rms`` metres.

    With ``coarsen`` > 1 the surface is synthesised on cells ``coarsen`` times larger and
    interpolated (bilinear) to the grid: for smooth surfaces (steep spectra) the detail
    lost is negligible and the FFT is ``coarsen``^2 times smaller.

    Returns (ny, nx) float32 heights with zero mean."""
    if rms == 0:
        return np.zeros(shape, dtype=np.float32)
    if coarsen > 1:
        small = tuple((n - 1 + coarsen - 1) // coarsen + 1 for n in shape)
        coarse = fractal_relief(small, cell_size * coarsen, rms, wavelength, beta, rng)
        return _upsample(coarse, coarsen, shape)
    ny, nx = (scipy.fft.next_fast_len(n, real=True) for n in shape)
    amplitude = _spectral_amplitude(ny, nx, float(cell_size), float(wavelength), float(beta))
    # single precision throughout: the surface is stored as float32 anyway.
    spectrum = np.empty(amplitude.shape, dtype=np.complex64)
    spectrum.real = amplitude * rng.standard_normal(amplitude.shape, dtype=np.float32)
    spectrum.imag = amplitude * rng.standard_normal(amplitude.shape, dtype=np.float32)
    surface = scipy.fft.irfft2(spectrum, s=(ny, nx), workers=-1)[: shape[0], : shape[1]]
    surface -= surface.mean(dtype=np.float64)
    std = surface.std(dtype=np.float64)
    surface *= np.float32(rms / std if std > 0 else 0.0)
    return np.ascontiguousarray(surface, dtype=np.float32)


@functools.lru_cache(maxsize=8)
def _spectral_amplitude(
    ny: int, nx: int, cell_size: float, wavelength: float, beta: float
) -> np.ndarray:
    """Amplitude of each rfft2 coefficient of :func:`fractal_relief` (read-only float32):
    independent of the seed, so kept for the next world of the same settings."""
    ky = scipy.fft.fftfreq(ny, d=cell_size).astype(np.float32)[:, None]
    kx = scipy.fft.rfftfreq(nx, d=cell_size).astype(np.float32)[None, :]
    k = np.maximum(np.hypot(kx, ky), np.float32(1.0 / wavelength))
    amplitude = (k * np.float32(wavelength)) ** np.float32(-beta / 2.0)
    amplitude[0, 0] = 0.0
    amplitude.flags.writeable = False
    return amplitude


def _upsample(coarse: np.ndarray, factor: int, shape: tuple[int, int]) -> np.ndarray:
    """Bilinear interpolation of ``coarse`` (cell i at fine index i * factor) to ``shape``,
    one separable axis at a time: along the rows, then along the columns."""
    lower, weight = [], []
    for axis, n in enumerate(shape):
        pos = np.arange(n, dtype=np.float64) / factor
        i0 = np.minimum(pos.astype(np.intp), coarse.shape[axis] - 2)
        lower.append(i0)
        weight.append((pos - i0).astype(np.float32))
    coarse = np.ascontiguousarray(coarse, dtype=np.float32)
    return upsample_rows_then_columns(coarse, lower[0], weight[0], lower[1], weight[1])


def power_law_sizes(
    n: int, smallest: float, largest: float, q: float, rng: np.random.Generator
) -> np.ndarray:
    """``n`` sizes in [smallest, largest] from a truncated cumulative power law
    N(>D) ~ D^-q (inverse-CDF sampling). Returns (n,) float64."""
    if smallest == largest:
        return np.full(n, float(smallest))
    u = rng.random(n)
    a, b = smallest**-q, largest**-q
    return (a - u * (a - b)) ** (-1.0 / q)


def poisson_points(
    density: float,
    extent: tuple[float, float, float, float],
    rng: np.random.Generator,
) -> np.ndarray:
    """Uniform Poisson points of ``density`` per m^2 over ``extent = (xmin, xmax, ymin,
    ymax)``. Returns (n, 2) ENU metres."""
    xmin, xmax, ymin, ymax = extent
    n = rng.poisson(density * (xmax - xmin) * (ymax - ymin))
    return np.column_stack((rng.uniform(xmin, xmax, n), rng.uniform(ymin, ymax, n)))


Profile = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def stamp(
    layer: np.ndarray,
    origin: tuple[float, float],
    cell_size: float,
    centers: np.ndarray,
    reach: np.ndarray,
    profile: Profile,
    combine: np.ufunc = np.maximum,
) -> None:
    """Stamp many features into ``layer`` in place, vectorised over features and cells.

    Args:
        layer: (ny, nx) float32 grid to update.
        origin: (x0, y0) of ``layer[0, 0]``'s cell centre, ENU metres.
        cell_size: metres.
        centers: (n, 2) feature centres (x, y), ENU metres.
        reach: (n,) metres beyond which a feature leaves the grid unchanged.
        profile: ``profile(dx, dy, index)`` -> values, where ``dx``, ``dy`` are
            (m, K, K) offsets in metres from the centres of the features ``index`` (m,);
            NaN where the feature does not touch a cell.
        combine: ufunc merging a value into the layer (``np.maximum``, ``np.add``...).
    """
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    if len(centers) == 0:
        return
    ny, nx = layer.shape
    flat = layer.reshape(-1)
    row, col, half, touch = stamp_boxes(layer.shape, origin, cell_size, centers, reach)
    for k in np.unique(half[touch]):
        members = np.flatnonzero(touch & (half == k))
        offsets = np.arange(-k, k + 1)
        per_feature = len(offsets) ** 2
        step = max(1, _BATCH_ELEMENTS // per_feature)
        for start in range(0, len(members), step):
            index = members[start : start + step]
            rows = row[index, None, None] + offsets[None, :, None]
            cols = col[index, None, None] + offsets[None, None, :]
            dx = origin[0] + cols * cell_size - centers[index, 0, None, None]
            dy = origin[1] + rows * cell_size - centers[index, 1, None, None]
            values = profile(dx, dy, index)
            keep = (rows >= 0) & (rows < ny) & (cols >= 0) & (cols < nx) & np.isfinite(values)
            rows, cols = np.broadcast_arrays(rows, cols)
            combine.at(flat, rows[keep] * nx + cols[keep], values[keep].astype(np.float32))


def stamp_boxes(
    shape: tuple[int, int],
    origin: tuple[float, float],
    cell_size: float,
    centers: np.ndarray,
    reach: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The square of cells :func:`stamp` evaluates each feature on: (row, col) of its
    centre cell, its half-size in cells, and whether it touches the grid (all (n,))."""
    ny, nx = shape
    centers = np.asarray(centers, dtype=np.float64).reshape(-1, 2)
    col = np.rint((centers[:, 0] - origin[0]) / cell_size).astype(np.intp)
    row = np.rint((centers[:, 1] - origin[1]) / cell_size).astype(np.intp)
    half = np.ceil(np.asarray(reach, dtype=np.float64) / cell_size).astype(np.intp)
    half = _LEVELS[np.minimum(np.searchsorted(_LEVELS, half), len(_LEVELS) - 1)]
    # Features wholly outside the grid are skipped.
    touch = (col + half >= 0) & (col - half < nx) & (row + half >= 0) & (row - half < ny)
    return row, col, half, touch


def smoothstep_edge(u: np.ndarray, width: float) -> np.ndarray:
    """0 -> 1 transition across u = 0 of steepness set by ``width`` (metres):
    0.5 (1 + tanh(u / width)); largest slope 1 / (2 width)."""
    return 0.5 * (1.0 + np.tanh(u / width))
