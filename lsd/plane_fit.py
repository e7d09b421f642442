"""Local plane fits over a sliding square window of an elevation grid, by box filters.

For every cell the inverse-variance weighted least-squares plane ``z = a + b x + c y``
through the observed cells of the window centred on it is found from windowed first and
second moments (box filters over a stack of masked single-precision products, with double
running sums, as :func:`cv2.boxFilter` computes them), so the cost is independent of the
window size. The moments and the fit run in one compiled pass:
:mod:`lsd.plane_fit_kernel`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from lsd import plane_fit_kernel as kernel


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
        gradient: the plane's rise per metre, ``tan(slope)`` (NaN if no fit).
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
    gradient: np.ndarray
    slope_error: np.ndarray
    roughness: np.ndarray
    roughness_error: np.ndarray
    step: np.ndarray
    step_error: np.ndarray
    sigma: np.ndarray
    observed_fraction: np.ndarray

    @cached_property
    def slope(self) -> np.ndarray:
        """Inclination of the plane, radians (NaN if no fit): computed when first asked for
        (the safe mask takes the arctangent only of the cells its other tests pass)."""
        with np.errstate(invalid="ignore"):
            return np.arctan(self.gradient)


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
    f32 = np.float32
    height = np.ascontiguousarray(height, dtype=np.float64)
    variance = np.ascontiguousarray(variance, dtype=np.float64)
    # Heights from a reference and coordinates from the grid centre keep the moments small
    # enough for single precision (the window sums are double). Any height near the data
    # will do as the reference: the median of an even subsample of the grid.
    ref = kernel.reference_height(height, max(1, int(np.sqrt(height.size / 4096))))
    none = np.zeros((0, 0))
    # One block for all the fields (fewer fresh pages than one array each). The gradient's
    # magnitude is computed in the kernel, each operation rounded once (OpenCV's
    # cv2.magnitude, used before, approximates it, a cell one way or another depending on
    # where the arrays happen to lie in memory); the slope is numpy's arctangent of it
    # (PlaneFit.slope).
    out = np.empty((9, *height.shape), f32)
    kernel.fit_rows(
        height, variance,
        none if top is None else np.ascontiguousarray(top, dtype=np.float64),
        none if cell_variance is None else np.ascontiguousarray(cell_variance, np.float64),
        ref, float(resolution), half, float(tolerance), out,
    )
    return PlaneFit(
        height=out[kernel.HEIGHT],
        gradient=out[kernel.GRADIENT],
        slope_error=out[kernel.SLOPE_ERROR],
        roughness=out[kernel.ROUGHNESS],
        roughness_error=out[kernel.ROUGHNESS_ERROR],
        step=out[kernel.STEP],
        step_error=out[kernel.STEP_ERROR],
        sigma=out[kernel.SIGMA],
        observed_fraction=out[kernel.FRACTION],
    )
