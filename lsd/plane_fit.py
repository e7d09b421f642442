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


def copy_where(dst: np.ndarray, src: np.ndarray | float, mask: np.ndarray) -> np.ndarray:
    """``dst[mask] = src`` in place, ``src`` a scalar or an array shaped as ``dst``.

    By OpenCV's masked copy (:func:`cv2.copyTo`): numpy's masked stores (``np.copyto`` with
    ``where``, boolean-index assignment, ``np.where``) are many times slower on the
    scattered masks of a map.

    Args:
        dst: 1-D or 2-D array (rows may be strided), modified in place and returned.
        src: scalar, or array of ``dst``'s shape.
        mask: bool array of ``dst``'s shape.
    """
    if dst.size == 0:
        return dst
    src = np.full_like(dst, src) if np.ndim(src) == 0 else np.asarray(src, dtype=dst.dtype)
    if cv2.copyTo(src, mask.view(np.uint8), dst) is not dst:  # could not write in place
        np.copyto(dst, src, where=mask)
    return dst


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
    cell_variance: np.ndarray | None = None,
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
        cell_variance: (n, m) variance whose window RMS is reported as ``sigma``, m^2, or
            None for ``variance``; for a pooled grid, the mean variance of the cells each
            pooled cell stands for, so that pooling does not make the map look more certain.

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
    copy_where(z, 0.0, hidden)
    var = variance.astype(f32)
    copy_where(var, 0.0, hidden)
    # Inverse-variance weights: a cell seen by few or far points counts less.
    with np.errstate(divide="ignore"):
        w = np.divide(f32(1.0), var)
    copy_where(w, 0.0, hidden)
    n0, n1 = height.shape
    x = ((np.arange(n0, dtype=f32) - n0 // 2) * f32(resolution))[:, None]
    y = ((np.arange(n1, dtype=f32) - n1 // 2) * f32(resolution))[None, :]
    wx, wy, wz = w * x, w * y, w * z

    def box(channel: np.ndarray) -> np.ndarray:
        # Window mean with zeros beyond the grid (scipy.ndimage.uniform_filter's
        # mode="constant"); one channel at a time is faster than one multi-channel pass.
        return cv2.boxFilter(channel, cv2.CV_32F, (size, size), borderType=cv2.BORDER_CONSTANT)

    frac = box(observed.view(np.uint8))
    sw, bx, by, bz = box(w), box(wx), box(wy), box(wz)
    # Below, every second moment is kept times the window's weight (C_ab = sw * cov(a, b)
    # = B(w a b) - B(w a) * mean_b, B the window mean): the plane and the slope need only
    # their ratios, and it saves normalising each. OpenCV's fused element operations
    # (accumulateProduct, scaleAdd, absdiff) make one pass where numpy makes two.
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = np.divide(f32(1.0), sw)
        # Window means, negated so that accumulateProduct subtracts.
        neg_mx = cv2.multiply(bx, inv, scale=-1.0)
        neg_my = cv2.multiply(by, inv, scale=-1.0)
        neg_mz = cv2.multiply(bz, inv, scale=-1.0)
        scratch = np.empty_like(w)

        def moment(a: np.ndarray, b: np.ndarray, box_a: np.ndarray, neg_mean_b: np.ndarray):
            out = box(np.multiply(a, b, out=scratch))
            cv2.accumulateProduct(box_a, neg_mean_b, out)
            return out

        cxx = moment(wx, x, bx, neg_mx)
        cxy = moment(wx, y, bx, neg_my)
        cyy = moment(wy, y, by, neg_my)
        cxz = moment(wz, x, bx, neg_mz)
        cyz = moment(wz, y, by, neg_mz)
        czz = moment(wz, z, bz, neg_mz)
        det = cxx * cyy
        det -= np.multiply(cxy, cxy, out=scratch)
        # Collinear or too few cells: no plane (det is ~0 relative to the spread).
        count = frac * f32(area)
        degenerate = np.square(sw, out=scratch)
        degenerate *= f32(1e-6 * resolution**4)
        failed = ~((count > 2.5) & (det > degenerate))
        inv_det = np.divide(f32(1.0), det, out=det)
        # NaN spreads from the gradient to every field derived from it.
        copy_where(inv_det, np.nan, failed)
        b = cyy * cxz
        b -= np.multiply(cxy, cyz, out=scratch)
        b *= inv_det
        c = cxx * cyz
        c -= np.multiply(cxy, cxz, out=scratch)
        c *= inv_det
        residual = czz
        residual -= np.multiply(b, cxz, out=scratch)
        residual -= np.multiply(c, cyz, out=scratch)
        residual *= inv
        # The weighted mean squared residual that noise alone produces: count / sum(w).
        noise_var = np.multiply(frac, inv, out=cxz)
        inv_weight = np.multiply(inv, f32(1.0 / area), out=inv)  # 1 / sum of the weights
        # plane = mean_z + b (x - mean_x) + c (y - mean_y)
        plane = np.add(neg_mx, x, out=neg_mx)
        plane *= b
        plane += np.multiply(c, np.add(neg_my, y, out=neg_my), out=scratch)
        plane -= neg_mz
        gradient = cv2.magnitude(b, c)
        slope = np.arctan(gradient)
        # Standard error of the gradient of a weighted least-squares plane:
        # sqrt(inv_weight / spread) with spread = (C_xx + C_yy) / (2 sw).
        spread = np.add(cxx, cyy, out=cxx)
        np.maximum(spread, f32(1e-30), out=spread)
        slope_error = np.divide(f32(2.0 / area), spread)
        np.sqrt(slope_error, out=slope_error)
        np.multiply(gradient, gradient, out=gradient)
        gradient += f32(1.0)
        slope_error /= gradient
        residual -= noise_var
        np.maximum(residual, f32(0.0), out=residual)
        roughness = np.sqrt(residual, out=residual)
        roughness_error = np.subtract(count, f32(3.0), out=cyy)
        np.maximum(roughness_error, f32(1.0), out=roughness_error)
        np.divide(f32(2.0), roughness_error, out=roughness_error)
        np.sqrt(roughness_error, out=roughness_error)
        roughness_error *= noise_var
        step = cv2.absdiff(z, plane)
        step_error = cv2.add(var, inv_weight)
        np.sqrt(step_error, out=step_error)
        if top is not None:
            # A percentile scatters about 1.7 times as much as the mean of the same points.
            top_step = np.subtract(top, ref, dtype=f32)
            top_step -= plane
            top_error = cv2.scaleAdd(var, 3.0, inv_weight)
            np.sqrt(top_error, out=top_error)
            use_top = cv2.scaleAdd(top_error, -tolerance, top_step) > cv2.scaleAdd(
                step_error, -tolerance, step
            )
            use_top &= observed
            copy_where(step, top_step, use_top)
            copy_where(step_error, top_error, use_top)
        if cell_variance is not None:
            var = cell_variance.astype(f32)
            copy_where(var, 0.0, hidden)
        sigma = box(var)
        sigma /= frac
        np.sqrt(sigma, out=sigma)
    for array in (roughness_error, step_error, sigma):
        copy_where(array, np.nan, failed)
    copy_where(step, np.nan, hidden)
    copy_where(step_error, np.nan, hidden)
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
