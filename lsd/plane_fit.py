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
    # Heights from a median and coordinates from the grid centre keep the moments small
    # enough for single precision (the filters' own running sums are double). The median
    # of an even subsample of the observed cells is as good a reference and much cheaper.
    cells = np.flatnonzero(observed)
    sample = height.reshape(-1)[cells[:: max(1, len(cells) // 4096)]]
    ref = float(np.median(sample)) if len(cells) else 0.0
    z = np.subtract(height, ref, dtype=f32)
    z[hidden] = 0.0
    var = variance.astype(f32)
    var[hidden] = 0.0
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
    sw, sx, sy, sz = box(w), box(wx), box(wy), box(wz)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / sw
        mx, my, mz = sx * inv, sy * inv, sz * inv
        # Weighted covariances of the window: E[ab] - E[a] E[b].
        cxx = box(wx * x) * inv - mx * mx
        cxy = box(wx * y) * inv - mx * my
        cyy = box(wy * y) * inv - my * my
        cxz = box(wz * x) * inv - mx * mz
        cyz = box(wz * y) * inv - my * mz
        czz = box(wz * z) * inv - mz * mz
        det = cxx * cyy - cxy * cxy
        # Collinear or too few cells: no plane (det is ~0 relative to the spread).
        count = frac * f32(area)
        failed = ~((count > 2.5) & (det > 1e-6 * resolution**4))
        inv_det = 1.0 / det
        b = (cyy * cxz - cxy * cyz) * inv_det
        c = (cxx * cyz - cxy * cxz) * inv_det
        residual = czz - b * cxz - c * cyz
        inv_weight = inv * f32(1.0 / area)  # 1 / sum of the window's weights
        # The weighted mean squared residual that noise alone produces: count / sum(w).
        noise_var = count * inv_weight
        plane = mz + b * (x - mx) + c * (y - my)
        gradient2 = b * b + c * c
        slope = np.arctan(np.sqrt(gradient2))
        # Standard error of the gradient of a weighted least-squares plane.
        spread = np.maximum(f32(0.5) * (cxx + cyy), f32(1e-12))
        slope_error = np.sqrt(inv_weight / spread) / (1.0 + gradient2)
        roughness = np.sqrt(np.maximum(residual - noise_var, 0.0))
        roughness_error = noise_var * np.sqrt(2.0 / np.maximum(count - 3.0, 1.0))
        step = np.abs(z - plane)
        step_error = np.sqrt(var + inv_weight)
        if top is not None:
            # A percentile scatters about 1.7 times as much as the mean of the same points.
            top_step = np.subtract(top, ref, dtype=f32) - plane
            top_error = np.sqrt(3.0 * var + inv_weight)
            use_top = top_step - tolerance * top_error > step - tolerance * step_error
            use_top &= observed
            np.copyto(step, top_step, where=use_top)
            np.copyto(step_error, top_error, where=use_top)
        sigma = np.sqrt(box(var) / frac)
    for array in (plane, slope, slope_error, roughness, roughness_error, step, step_error, sigma):
        array[failed] = np.nan
    step[hidden] = np.nan
    step_error[hidden] = np.nan
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
