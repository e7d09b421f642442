"""The window plane fits of :func:`lsd.plane_fit.fit_planes` as one compiled pass (numba).

The vectorised version this replaces (git history: lsd/plane_fit.py before the kernel) ran
twelve OpenCV box filters and some seventy numpy and OpenCV element operations over the
grid, each a pass through memory. This kernel streams the grid row by row: a row's window
terms, their twelve running row sums side by side, the column sums over a ring of ``size``
rows, and each output row's fit as soon as its window sums are complete. Every stage but
the running row sums keeps each moment in its own row of cells (channel by channel), so
that LLVM vectorises the terms, the column sums and the fit across cells (the fit in two
loops: more stores in one loop make it give up); the results do not depend on it, since
each cell's arithmetic is the same in a vector lane as in scalar code.

It gives the vectorised version's results bit for bit because it repeats its arithmetic:
OpenCV's box filter (:func:`cv2.boxFilter`, normalised, zero border) keeps double running
sums, a row's first sum taken left to right and then ``s += S[i + size] - S[i]`` (sizes 3
and 5 summed outright), a column sum to which each new row is added before the output and
from which the row leaving the window is subtracted after it, the output
``float(sum * (1 / size**2))``; for the uint8 mask the whole-number count times
``float32(1 / size**2)``, but in double precision in the last ``n % 4`` columns, which its
four-lane loop leaves to scalar code. ``cv2.accumulateProduct`` and ``cv2.scaleAdd`` are
fused multiply-adds on float32; every other operation is a single-precision one in the
vectorised version's order. The gradient's magnitude is ``sqrt(b^2 + c^2)`` with each
operation rounded once (OpenCV's approximation rounded some cells by where the arrays lie);
its arctangent is numpy's, taken by the caller (:attr:`lsd.plane_fit.PlaneFit.slope`).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.core.extending import intrinsic

_F = np.float32
_D = np.float64


@intrinsic
def _fma(typingctx, a, b, c):
    """``a * b + c`` with one rounding (LLVM's fma), in the arguments' precision."""
    sig = a(a, b, c)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _nan_max(a, b):
    """``np.maximum`` of two scalars (NaN wins)."""
    if a != a or b != b:
        return a + b
    return a if a >= b else b


# The moments, one row of cells each: w, w x, w y, w z, w x x, w x y, w y y, w z x, w z y,
# w z z, sigma's variance, observed
_CHANNELS = 12
# The planes of fit_rows' output, in order.
GRADIENT, SLOPE_ERROR, ROUGHNESS, ROUGHNESS_ERROR, HEIGHT, STEP, STEP_ERROR, SIGMA, FRACTION = (
    range(9)
)


@njit(cache=True, nogil=True, error_model="numpy")
def _load_row(height, variance, cell_variance, r, x, y_of, f_ref, half, terms):
    """Row ``r``'s window terms, each moment in its row of ``terms`` (single precision,
    after ``half`` zero cells): w, w x, w y, w z, w x x, w x y, w y y, w z x, w z y, w z z,
    the variance for sigma and the observed flag."""
    n1 = height.shape[1]
    one = _F(1.0)
    zero = _F(0.0)
    for j in range(n1):
        h = height[r, j]
        v = variance[r, j]
        seen = np.isfinite(h) & np.isfinite(v) & (v > 0)
        z = (_F(h) - f_ref) if seen else zero
        var = _F(v) if seen else zero
        w = (one / var) if seen else zero
        y = y_of[j]
        wx = w * x
        wy = w * y
        wz = w * z
        p = j + half
        terms[0, p] = w
        terms[1, p] = wx
        terms[2, p] = wy
        terms[3, p] = wz
        terms[4, p] = wx * x
        terms[5, p] = wx * y
        terms[6, p] = wy * y
        terms[7, p] = wz * x
        terms[8, p] = wz * y
        terms[9, p] = wz * z
        terms[11, p] = one if seen else zero
        if cell_variance.shape[0] == 0:
            terms[10, p] = var
    if cell_variance.shape[0] > 0:
        for j in range(n1):
            h = height[r, j]
            v = variance[r, j]
            seen = np.isfinite(h) & np.isfinite(v) & (v > 0)
            terms[10, j + half] = _F(cell_variance[r, j]) if seen else zero


@njit(cache=True, nogil=True, error_model="numpy")
def _row_sums(terms, size, out):
    """OpenCV's RowSum<float, double> of every moment's padded row: ``out[ch, j]`` = sum of
    ``terms[ch, j + t]`` for t < ``size``, in double precision."""
    cells = out.shape[1]
    if size == 3:
        for ch in range(_CHANNELS):
            a = terms[ch]
            o = out[ch]
            for k in range(cells):
                o[k] = _D(a[k]) + _D(a[k + 1]) + _D(a[k + 2])
        return
    if size == 5:
        for ch in range(_CHANNELS):
            a = terms[ch]
            o = out[ch]
            for k in range(cells):
                o[k] = (_D(a[k]) + _D(a[k + 1]) + _D(a[k + 2]) + _D(a[k + 3])
                        + _D(a[k + 4]))
        return
    for ch in range(_CHANNELS):
        s = 0.0
        for t in range(size):
            s += _D(terms[ch, t])
        out[ch, 0] = s
    # The twelve running sums side by side (independent chains overlap; a vector across
    # moments would need LLVM's SLP vectoriser, which numba leaves off).
    t0, t1, t2, t3, t4, t5 = terms[0], terms[1], terms[2], terms[3], terms[4], terms[5]
    t6, t7, t8, t9, t10, t11 = terms[6], terms[7], terms[8], terms[9], terms[10], terms[11]
    s0, s1, s2, s3, s4, s5 = out[0, 0], out[1, 0], out[2, 0], out[3, 0], out[4, 0], out[5, 0]
    s6, s7, s8, s9, s10, s11 = out[6, 0], out[7, 0], out[8, 0], out[9, 0], out[10, 0], out[11, 0]
    for k in range(1, cells):
        e = k - 1 + size
        g = k - 1
        s0 += _D(t0[e]) - _D(t0[g])
        s1 += _D(t1[e]) - _D(t1[g])
        s2 += _D(t2[e]) - _D(t2[g])
        s3 += _D(t3[e]) - _D(t3[g])
        s4 += _D(t4[e]) - _D(t4[g])
        s5 += _D(t5[e]) - _D(t5[g])
        s6 += _D(t6[e]) - _D(t6[g])
        s7 += _D(t7[e]) - _D(t7[g])
        s8 += _D(t8[e]) - _D(t8[g])
        s9 += _D(t9[e]) - _D(t9[g])
        s10 += _D(t10[e]) - _D(t10[g])
        s11 += _D(t11[e]) - _D(t11[g])
        out[0, k] = s0
        out[1, k] = s1
        out[2, k] = s2
        out[3, k] = s3
        out[4, k] = s4
        out[5, k] = s5
        out[6, k] = s6
        out[7, k] = s7
        out[8, k] = s8
        out[9, k] = s9
        out[10, k] = s10
        out[11, k] = s11


@njit(cache=True, nogil=True, error_model="numpy")
def _window_row(col, entering, leaving, scale, window):
    """The output row's window sums: the column sums plus the entering row's row sums,
    scaled into ``window`` (single precision; the observed count unscaled, a whole number);
    then the row leaving the window is subtracted from the column sums."""
    for ch in range(_CHANNELS):
        c = col[ch]
        e = entering[ch]
        g = leaving[ch]
        w = window[ch]
        factor = 1.0 if ch == _CHANNELS - 1 else scale
        for j in range(c.shape[0]):
            s = c[j] + e[j]
            w[j] = _F(s * factor)
            c[j] = s - g[j]


@njit(cache=True, nogil=True, error_model="numpy")
def _fit_row(height, variance, top, i, x, y_of, window, plane_row, out, simd_cols, size, ref,
             resolution, tolerance):
    """Output row ``i``'s fits from its window sums ``window`` (see :func:`fit_rows`)."""
    n1 = height.shape[1]
    area = float(size * size)
    scale = 1.0 / area
    f_scale = _F(1.0 / area)
    f_area = _F(area)
    f_ref = _F(ref)
    f_degenerate = _F(1e-6 * resolution**4)
    f_two_area = _F(2.0 / area)
    f_neg_tol = _F(-tolerance)
    one = _F(1.0)
    zero = _F(0.0)
    nan = _F(np.nan)
    # The plane and what it alone decides (at most eight stores, or LLVM leaves the loop
    # scalar); its height and weight (NaN: no fit) kept for the step loop below.
    for j in range(n1):
        cnt = window[11, j]
        # OpenCV scales the mask's counts in single precision four columns at a time and
        # the columns left over in double precision.
        frac = cnt * f_scale if j < simd_cols else _F(cnt * scale)
        sw = window[0, j]
        bx = window[1, j]
        by = window[2, j]
        bz = window[3, j]
        inv = one / sw
        neg_mx = -(bx * inv)
        neg_my = -(by * inv)
        neg_mz = -(bz * inv)
        cxx = _fma(bx, neg_mx, window[4, j])
        cxy = _fma(bx, neg_my, window[5, j])
        cyy = _fma(by, neg_my, window[6, j])
        cxz = _fma(bx, neg_mz, window[7, j])
        cyz = _fma(by, neg_mz, window[8, j])
        czz = _fma(bz, neg_mz, window[9, j])
        det = cxx * cyy - cxy * cxy
        count = frac * f_area
        failed = not ((count > _F(2.5)) & (det > (sw * sw) * f_degenerate))
        inv_det = nan if failed else one / det
        b = (cyy * cxz - cxy * cyz) * inv_det
        c = (cxx * cyz - cxy * cxz) * inv_det
        residual = ((czz - b * cxz) - c * cyz) * inv
        noise_var = frac * inv
        plane = (neg_mx + x) * b + c * (neg_my + y_of[j]) - neg_mz
        spread = _nan_max(cxx + cyy, _F(1e-30))
        gradient = np.sqrt(b * b + c * c)
        out[GRADIENT, i, j] = gradient
        out[SLOPE_ERROR, i, j] = np.sqrt(f_two_area / spread) / (gradient * gradient + one)
        out[ROUGHNESS, i, j] = np.sqrt(_nan_max(residual - noise_var, zero))
        out[ROUGHNESS_ERROR, i, j] = (
            nan if failed else np.sqrt(_F(2.0) / _nan_max(count - _F(3.0), one)) * noise_var
        )
        out[HEIGHT, i, j] = plane + f_ref
        plane_row[0, j] = plane
        plane_row[1, j] = nan if failed else inv * f_scale
    has_top = top.shape[0] > 0
    for j in range(n1):
        cnt = window[11, j]
        frac = cnt * f_scale if j < simd_cols else _F(cnt * scale)
        plane = plane_row[0, j]
        inv_weight = plane_row[1, j]  # NaN where the fit failed
        h = height[i, j]
        v = variance[i, j]
        seen = np.isfinite(h) & np.isfinite(v) & (v > 0)
        z = (_F(h) - f_ref) if seen else zero
        var = _F(v) if seen else zero
        step = abs(z - plane)
        step_error = np.sqrt(var + inv_weight)
        if has_top:
            top_step = (_F(top[i, j]) - f_ref) - plane
            top_error = np.sqrt(_fma(var, _F(3.0), inv_weight))
            higher = seen & (
                _fma(top_error, f_neg_tol, top_step) > _fma(step_error, f_neg_tol, step)
            )
            step = top_step if higher else step
            step_error = top_error if higher else step_error
        sigma = np.sqrt(window[10, j] / frac)
        out[STEP, i, j] = step if seen else nan
        out[STEP_ERROR, i, j] = step_error if seen else nan
        out[SIGMA, i, j] = nan if inv_weight != inv_weight else sigma
        out[FRACTION, i, j] = min(max(frac, zero), one)


@njit(cache=True, nogil=True, error_model="numpy")
def fit_rows(height, variance, top, cell_variance, ref, resolution, half, tolerance, out):
    """Every cell's window fit, written into ``out``.

    Args:
        height, variance: (n0, n1) float64 map heights (NaN: unobserved) and variances.
        top: (n0, n1) float64 cell tops, or a (0, 0) array for none.
        cell_variance: (n0, n1) float64 variance for ``sigma``, or (0, 0) for ``variance``.
        ref: the reference height (as :func:`fit_planes` picks it).
        resolution: cell side, m; half: window half-side, cells; tolerance: step tolerance.
        out: (9, n0, n1) float32, the planes ``GRADIENT`` .. ``FRACTION`` (the fields of
            :class:`PlaneFit` of those names; ``HEIGHT`` is its ``height``, the plane's
            height at the cell, ENU z).
    """
    n0, n1 = height.shape
    size = 2 * half + 1
    scale = 1.0 / float(size * size)
    f_ref = _F(ref)
    f_res = _F(resolution)
    simd_cols = n1 - n1 % 4
    x_of = np.empty(n0, _F)
    y_of = np.empty(n1, _F)
    for i in range(n0):
        x_of[i] = (_F(i) - _F(n0 // 2)) * f_res
    for j in range(n1):
        y_of[j] = (_F(j) - _F(n1 // 2)) * f_res
    nc = _CHANNELS
    # Ring of the last `size` rows' row sums (double; the observed count too, whose sums
    # are whole numbers and so exact in any order), the column sums.
    ring = np.zeros((size, nc, n1))
    col = np.zeros((nc, n1))
    terms = np.zeros((nc, n1 + 2 * half), _F)
    window = np.empty((nc, n1), _F)
    plane_row = np.empty((2, n1), _F)
    # The column sums start with the size - 1 rows above the first output row.
    for r in range(-half, n0 + half):
        row = ring[(r + size) % size]
        if 0 <= r < n0:
            _load_row(height, variance, cell_variance, r, x_of[r], y_of, f_ref, half, terms)
            _row_sums(terms, size, row)
        else:
            row[:] = 0.0
        if r < half:
            col += row
            continue
        i = r - half
        _window_row(col, row, ring[(i - half + size) % size], scale, window)
        _fit_row(height, variance, top, i, x_of[i], y_of, window, plane_row, out, simd_cols,
                 size, ref, resolution, tolerance)


@njit(cache=True, nogil=True, error_model="numpy")
def reference_height(height: np.ndarray, stride: int) -> float:
    """The median of the finite heights of every ``stride``-th row and column (of all the
    finite heights when none of those is; 0 when none is): numpy's median of the same values
    (the middle one, or the mean of the middle two, which are the same order statistics
    whichever way they are found)."""
    n0, n1 = height.shape
    sample = np.empty(((n0 + stride - 1) // stride) * ((n1 + stride - 1) // stride))
    count = 0
    for i in range(0, n0, stride):
        for j in range(0, n1, stride):
            if np.isfinite(height[i, j]):
                sample[count] = height[i, j]
                count += 1
    if count == 0:
        sample = np.empty(n0 * n1)
        for i in range(n0):
            for j in range(n1):
                if np.isfinite(height[i, j]):
                    sample[count] = height[i, j]
                    count += 1
        if count == 0:
            return 0.0
    return np.median(sample[:count])
