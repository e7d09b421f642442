"""Local plane fits over a sliding square window of an elevation grid, by box filters.

For every cell the inverse-variance weighted least-squares plane ``z = a + b x + c y``
through the observed cells of the window centred on it is found from windowed first and
second moments (an OpenCV box filter, :func:`cv2.boxFilter`, over each of a stack of masked
single-precision products; its running sums are double), so the cost is independent of the
window size and there is no loop over cells.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class PlaneFit:
    """Per-cell results of the window plane fit; every array is (n, n) float32.

    Attributes:
        height: fitted plane height at the cell centre, ENU z metres (NaN if no fit).
        slope: inclination of the plane, radians (NaN if no fit).
        slope_error: approximate 1-sigma error of ``slope`` from the measurement noise, rad.
        roughness: weighted RMS residual of the fit with the part that measurement noise
            explains removed, ``sqrt(max(0, residual_var - noise_var))`` where ``noise_var``
            is the harmonic mean of the cell variances, metres (NaN if no fit).
        roughness_error: approximate 1-sigma error of ``roughness**2`` from the measurement
            noise, ``noise_var * sqrt(2 / (cells - 3))``, m^2.
        step: ``|cell height - plane height|`` or ``cell top - plane height`` at the cell
            itself, whichever stands out more beyond its error, metres (NaN where the cell
            is unobserved): how far the cell sticks out of (or into) its footprint plane.
        step_error: 1-sigma error of ``step``, metres.
        sigma: RMS 1-sigma height error of the window's observed cells, metres.
        observed_fraction: fraction of the window's cells that are observed, [0, 1].
    """

    height: np.ndarray
    slope: np.ndarray
    slope_error: np.ndarray
    roughness: np.ndarray
    roughness_error: np.ndarray
    step: np.ndarray
    step_error: np.ndarray
    sigma: np.ndarray
    observed_fraction: np.ndarray


def fit_planes(
    height: np.ndarray,
    variance: np.ndarray,
    resolution: float,
    radius: float,
    top: np.ndarray | None = None,
    tolerance: float = 0.0,
) -> PlaneFit:
    """Fit a plane in the square window of half-side ``radius`` around every cell.

    Args:
        height: (n, m) cell heights, metres; NaN = unobserved.
        variance: (n, m) variance of the heights, m^2 (ignored where ``height`` is NaN).
        resolution: cell side, metres.
        radius: half-side of the window, metres (rounded to whole cells, at least one).
        top: (n, m) top of each cell, metres, or None (only ``step`` uses it).
        tolerance: how many standard errors the step test will forgive; decides whether
            the mean's or the top's step (each less that many errors) is the larger.

    Returns:
        a :class:`PlaneFit`. A cell gets a fit only when its window holds at least three
        observed cells that are not collinear.
    """
    half = max(1, int(round(radius / resolution)))
    size = 2 * half + 1
    area = float(size * size)
    f32 = np.float32
    with np.errstate(invalid="ignore"):
        observed = np.isfinite(height) & np.isfinite(variance) & (variance > 0)
    hidden = ~observed
    # Heights from a reference and coordinates from the grid centre keep the moments small
    # enough for single precision (the filters' own running sums are double). Any height
    # near the data will do as the reference: the median of an even subsample of the grid.
    stride = max(1, int(np.sqrt(height.size / 4096)))
    sample = height[::stride, ::stride]
    sample = sample[np.isfinite(sample)]
    if len(sample) == 0:
        sample = height[np.isfinite(height)]
    ref = float(np.median(sample)) if len(sample) else 0.0
    z = np.subtract(height, ref, dtype=f32)
    np.copyto(z, f32(0.0), where=hidden)
    var = variance.astype(f32)
    np.copyto(var, f32(0.0), where=hidden)
    # Inverse-variance weights: a cell seen by few or far points counts less.
    w = np.zeros(height.shape, f32)
    np.divide(f32(1.0), var, out=w, where=observed)
    n0, n1 = height.shape
    x = ((np.arange(n0, dtype=f32) - n0 // 2) * f32(resolution))[:, None]
    y = ((np.arange(n1, dtype=f32) - n1 // 2) * f32(resolution))[None, :]
    wx, wy, wz = w * x, w * y, w * z

    def box(channel: np.ndarray) -> np.ndarray:
        # Window mean with zeros beyond the grid (scipy.ndimage.uniform_filter's
        # mode="constant"); one channel at a time is faster than one multi-channel pass.
        return cv2.boxFilter(channel, cv2.CV_32F, (size, size), borderType=cv2.BORDER_CONSTANT)

    frac = box(observed.view(np.uint8))
    sw, mx, my, mz = box(w), box(wx), box(wy), box(wz)
    # In-place arithmetic from here on: fewer fresh (n, m) arrays, less memory traffic.
    scratch = np.empty_like(w)

    def covariance(a: np.ndarray, b: np.ndarray, mean_a: np.ndarray, mean_b: np.ndarray):
        # Weighted covariance of the window, E[ab] - E[a] E[b] (a, b already weighted once).
        out = box(np.multiply(a, b, out=scratch))
        out *= inv
        out -= np.multiply(mean_a, mean_b, out=scratch)
        return out

    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.divide(f32(1.0), sw)
        mx *= inv
        my *= inv
        mz *= inv
        cxx = covariance(wx, x, mx, mx)
        cxy = covariance(wx, y, mx, my)
        cyy = covariance(wy, y, my, my)
        cxz = covariance(wz, x, mx, mz)
        cyz = covariance(wz, y, my, mz)
        czz = covariance(wz, z, mz, mz)
        det = cxx * cyy
        det -= np.multiply(cxy, cxy, out=scratch)
        # Collinear or too few cells: no plane (det is ~0 relative to the spread).
        count = frac * f32(area)
        failed = ~((count > 2.5) & (det > 1e-6 * resolution**4))
        inv_det = np.divide(f32(1.0), det, out=det)
        b = cyy * cxz
        b -= np.multiply(cxy, cyz, out=scratch)
        b *= inv_det
        c = cxx * cyz
        c -= np.multiply(cxy, cxz, out=scratch)
        c *= inv_det
        residual = czz
        residual -= np.multiply(b, cxz, out=scratch)
        residual -= np.multiply(c, cyz, out=scratch)
        inv_weight = inv
        inv_weight *= f32(1.0 / area)  # 1 / sum of the window's weights
        # The weighted mean squared residual that noise alone produces: count / sum(w).
        noise_var = count * inv_weight
        plane = np.subtract(x, mx, out=mx)
        plane *= b
        plane += np.multiply(c, np.subtract(y, my, out=scratch), out=scratch)
        plane += mz
        gradient2 = np.multiply(b, b, out=b)
        gradient2 += np.multiply(c, c, out=c)
        slope = np.sqrt(gradient2)
        np.arctan(slope, out=slope)
        # Standard error of the gradient of a weighted least-squares plane.
        spread = np.add(cxx, cyy, out=cxx)
        spread *= f32(0.5)
        np.maximum(spread, f32(1e-12), out=spread)
        slope_error = np.divide(inv_weight, spread, out=spread)
        np.sqrt(slope_error, out=slope_error)
        gradient2 += f32(1.0)
        slope_error /= gradient2
        residual -= noise_var
        np.maximum(residual, f32(0.0), out=residual)
        roughness = np.sqrt(residual, out=residual)
        roughness_error = np.subtract(count, f32(3.0), out=cyy)
        np.maximum(roughness_error, f32(1.0), out=roughness_error)
        np.divide(f32(2.0), roughness_error, out=roughness_error)
        np.sqrt(roughness_error, out=roughness_error)
        roughness_error *= noise_var
        step = np.subtract(z, plane, out=cxz)
        np.abs(step, out=step)
        step_error = var + inv_weight
        np.sqrt(step_error, out=step_error)
        if top is not None:
            # A percentile scatters about 1.7 times as much as the mean of the same points.
            top_step = np.subtract(top, ref, dtype=f32)
            top_step -= plane
            top_error = np.multiply(var, f32(3.0), out=cyz)
            top_error += inv_weight
            np.sqrt(top_error, out=top_error)
            use_top = top_step - tolerance * top_error > step - tolerance * step_error
            use_top &= observed
            np.copyto(step, top_step, where=use_top)
            np.copyto(step_error, top_error, where=use_top)
        sigma = box(var)
        sigma /= frac
        np.sqrt(sigma, out=sigma)
    for array in (plane, slope, slope_error, roughness, roughness_error, step, step_error, sigma):
        np.copyto(array, f32(np.nan), where=failed)
    np.copyto(step, f32(np.nan), where=hidden)
    np.copyto(step_error, f32(np.nan), where=hidden)
    plane += f32(ref)
    return PlaneFit(
        height=plane,
        slope=slope,
        slope_error=slope_error,
        roughness=roughness,
        roughness_error=roughness_error,
        step=step,
        step_error=step_error,
        sigma=sigma,
        observed_fraction=np.clip(frac, f32(0.0), f32(1.0), out=frac),
    )
