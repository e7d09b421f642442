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
    observed = np.isfinite(height) & np.isfinite(variance) & (variance > 0)
    f32 = np.float32
    o = observed.astype(f32)
    # Inverse-variance weights: a cell seen by few or far points counts less.
    w = np.where(observed, 1.0 / np.where(observed, variance, 1.0), 0.0).astype(f32)
    # Heights from their median and coordinates from the grid centre keep the moments
    # small enough for single precision (the filters' own running sums are double).
    ref = float(np.median(height[observed])) if observed.any() else 0.0
    z = np.where(observed, height - ref, 0.0).astype(f32)
    var = np.where(observed, variance, 0.0).astype(f32)
    n0, n1 = height.shape
    x = ((np.arange(n0, dtype=f32) - n0 // 2) * f32(resolution))[:, None] * np.ones((1, n1), f32)
    y = ((np.arange(n1, dtype=f32) - n1 // 2) * f32(resolution))[None, :] * np.ones((n0, 1), f32)
    wx, wy, wz = w * x, w * y, w * z
    # Window means with zeros beyond the grid (as scipy.ndimage.uniform_filter, mode
    # "constant"); one channel at a time is faster than one multi-channel pass.
    frac, svar, sw, sx, sy, sz, sxx, sxy, syy, sxz, syz, szz = (
        cv2.boxFilter(channel, -1, (size, size), borderType=cv2.BORDER_CONSTANT)
        for channel in (o, var, w, wx, wy, wz, wx * x, wx * y, wy * y, wz * x, wz * y, wz * z)
    )
    count = frac * size * size
    with np.errstate(divide="ignore", invalid="ignore"):
        weight = sw * size * size  # sum of the window's weights
        inv = 1.0 / sw
        mx, my, mz = sx * inv, sy * inv, sz * inv
        cxx = sxx * inv - mx * mx
        cxy = sxy * inv - mx * my
        cyy = syy * inv - my * my
        cxz = sxz * inv - mx * mz
        cyz = syz * inv - my * mz
        czz = szz * inv - mz * mz
        det = cxx * cyy - cxy * cxy
        # Collinear or too few cells: no plane (det is ~0 relative to the spread).
        ok = (count > 2.5) & (det > 1e-6 * resolution**4)
        b = (cyy * cxz - cxy * cyz) / det
        c = (cxx * cyz - cxy * cxz) / det
        residual = czz - b * cxz - c * cyz
        # The weighted mean squared residual that noise alone produces: count / sum(w).
        noise_var = count / weight
        plane = mz + b * (x - mx) + c * (y - my)
        gradient = np.hypot(b, c)
        slope = np.arctan(gradient)
        # Standard error of the gradient of a weighted least-squares plane.
        gradient_error = np.sqrt(1.0 / (weight * np.maximum(0.5 * (cxx + cyy), 1e-12)))
        slope_error = gradient_error / (1.0 + gradient * gradient)
        roughness = np.sqrt(np.maximum(residual - noise_var, 0.0))
        roughness_error = noise_var * np.sqrt(2.0 / np.maximum(count - 3.0, 1.0))
        step = np.abs(z - plane)
        cell_var = np.where(observed, var, np.inf)
        step_error = np.sqrt(cell_var + 1.0 / weight)
        if top is not None:
            # A percentile scatters about 1.7 times as much as the mean of the same points.
            top_step = np.where(observed, top - ref, 0.0).astype(f32) - plane
            top_error = np.sqrt(3.0 * cell_var + 1.0 / weight)
            use_top = top_step - tolerance * top_error > step - tolerance * step_error
            step = np.where(use_top, top_step, step)
            step_error = np.where(use_top, top_error, step_error)
        sigma = np.sqrt(svar / frac)
    for array in (plane, slope, slope_error, roughness, roughness_error, step, step_error, sigma):
        array[~ok] = np.nan
    step[~observed] = np.nan
    step_error[~observed] = np.nan
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
        observed_fraction=np.clip(frac, 0.0, 1.0),
    )
