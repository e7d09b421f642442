"""The window plane fits of :func:`lsd.plane_fit.fit_planes` as one compiled pass (numba).

The vectorised version this replaces (git history: lsd/plane_fit.py before the kernel) ran
twelve OpenCV box filters and some seventy numpy and OpenCV element operations over the
grid, each a pass through memory. This kernel streams the grid row by row: the running row
sums of all the moments together, their column sums over a ring of ``size`` rows, and each
output row's fit as soon as its window sums are complete.

It gives the vectorised version's results bit for bit because it repeats its arithmetic:
OpenCV's box filter (:func:`cv2.boxFilter`, normalised, zero border) keeps double running
sums, a row's first sum taken left to right and then ``s += S[i + size] - S[i]`` (sizes 3
and 5 summed outright), a column sum to which each new row is added before the output and
from which the row leaving the window is subtracted after it, the output
``float(sum * (1 / size**2))``; for the uint8 mask the whole-number count times
``float32(1 / size**2)``, but in double precision in the last ``n % 4`` columns, which its
four-lane loop leaves to scalar code. ``cv2.accumulateProduct`` and ``cv2.scaleAdd`` are
fused multiply-adds on float32; every other operation is a single-precision one in the
vectorised version's order. The gradient's magnitude and its arctangent stay OpenCV's and
numpy's (their own approximations, computed by the caller).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.core.extending import intrinsic

_F = np.float32


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


# w, w x, w y, w z, w x x, w x y, w y y, w z x, w z y, w z z, sigma's variance, observed
_CHANNELS = 12


@njit(cache=True, nogil=True, error_model="numpy")
def _row_sums(values: np.ndarray, size: int, channels: int, out: np.ndarray) -> None:
    """OpenCV's RowSum<float, double> of one padded row of interleaved channels, every
    channel at once (their running sums are independent, so they overlap): ``out[j * C +
    ch]`` = sum of ``values[(j + t) * C + ch]`` for t < ``size`` (``values`` holds the row
    with ``size // 2`` zero cells each side)."""
    c = channels
    n = len(out)
    if size == 3:
        for k in range(n):
            out[k] = values[k] + values[k + c] + values[k + 2 * c]
    elif size == 5:
        for k in range(n):
            out[k] = (values[k] + values[k + c] + values[k + 2 * c] + values[k + 3 * c]
                      + values[k + 4 * c])
    else:
        # Through 2-D views (a cell per row) the running sums, four channels at a time in
        # registers (four chains overlap), compile to half the time of flat indexing.
        cells = n // c
        v = values.reshape((cells + size - 1, c))
        o = out.reshape((cells, c))
        for ch in range(c):
            s = 0.0
            for t in range(size):
                s += v[t, ch]
            o[0, ch] = s
        for g in range(0, c, 4):
            s0, s1, s2, s3 = o[0, g], o[0, g + 1], o[0, g + 2], o[0, g + 3]
            for k in range(1, cells):
                entering = v[k - 1 + size]
                leaving = v[k - 1]
                s0 += entering[g] - leaving[g]
                s1 += entering[g + 1] - leaving[g + 1]
                s2 += entering[g + 2] - leaving[g + 2]
                s3 += entering[g + 3] - leaving[g + 3]
                row = o[k]
                row[g] = s0
                row[g + 1] = s1
                row[g + 2] = s2
                row[g + 3] = s3


@njit(cache=True, nogil=True, error_model="numpy")
def _load_row(height, variance, cell_variance, r, x, y_of, f_ref, half, padded,
              observed, zf, varf):
    """Row ``r``'s cells: the mask and single-precision height and variance (into
    ``observed``, ``zf``, ``varf``) and the interleaved window terms (into ``padded``, after
    ``half`` zero cells): w, w x, w y, w z, w x x, w x y, w y y, w z x, w z y, w z z, the
    variance for sigma and the observed flag."""
    n1 = height.shape[1]
    c = _CHANNELS
    one = _F(1.0)
    zero = _F(0.0)
    has_cell_var = cell_variance.shape[0] > 0
    for j in range(n1):
        h = height[r, j]
        v = variance[r, j]
        seen = np.isfinite(h) and np.isfinite(v) and v > 0
        observed[r, j] = seen
        if seen:
            z = _F(h) - f_ref
            var = _F(v)
            w = one / var
        else:
            z = zero
            var = zero
            w = zero
        zf[r, j] = z
        varf[r, j] = var
        y = y_of[j]
        wx = w * x
        wy = w * y
        wz = w * z
        p = (j + half) * c
        padded[p] = w
        padded[p + 1] = wx
        padded[p + 2] = wy
        padded[p + 3] = wz
        padded[p + 4] = wx * x
        padded[p + 5] = wx * y
        padded[p + 6] = wy * y
        padded[p + 7] = wz * x
        padded[p + 8] = wz * y
        padded[p + 9] = wz * z
        if has_cell_var:
            padded[p + 10] = _F(cell_variance[r, j]) if seen else zero
        else:
            padded[p + 10] = var
        padded[p + 11] = 1.0 if seen else 0.0


@njit(cache=True, nogil=True, error_model="numpy")
def _load(height, variance, cell_variance, r, x_of, y_of, f_ref, half, size, padded,
          observed, zf, varf, out):
    """Row ``r``'s row sums into ``out`` (zeros beyond the grid)."""
    if r < 0 or r >= height.shape[0]:
        out[:] = 0.0
        return
    _load_row(height, variance, cell_variance, r, x_of[r], y_of, f_ref, half, padded,
              observed, zf, varf)
    _row_sums(padded, size, _CHANNELS, out)


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


@njit(cache=True, nogil=True, error_model="numpy")
def gradient_magnitude(b: np.ndarray, c: np.ndarray, slope_error: np.ndarray) -> np.ndarray:
    """(n0, n1) float32 ``sqrt(b^2 + c^2)`` of :func:`fit_rows`'s gradient components, each
    operation rounded once (the same bits wherever the arrays lie), and ``slope_error``
    divided in place by ``1 + gradient^2``."""
    n0, n1 = b.shape
    out = np.empty((n0, n1), _F)
    one = _F(1.0)
    for i in range(n0):
        for j in range(n1):
            x = b[i, j]
            y = c[i, j]
            g = np.sqrt(x * x + y * y)
            out[i, j] = g
            slope_error[i, j] /= g * g + one
    return out


@njit(cache=True, nogil=True, error_model="numpy")
def fit_rows(
    height, variance, top, cell_variance, ref, resolution, half, tolerance,
    b_out, c_out, plane_out, slope_error_out, roughness_out, roughness_error_out,
    step_out, step_error_out, sigma_out, fraction_out,
):
    """Every cell's window fit, written into the (n0, n1) float32 outputs.

    Args:
        height, variance: (n0, n1) float64 map heights (NaN: unobserved) and variances.
        top: (n0, n1) float64 cell tops, or a (0, 0) array for none.
        cell_variance: (n0, n1) float64 variance for ``sigma``, or (0, 0) for ``variance``.
        ref: the reference height (as :func:`fit_planes` picks it).
        resolution: cell side, m; half: window half-side, cells; tolerance: step tolerance.
        b_out, c_out: the plane's gradient (NaN where no fit): its magnitude and slope are
            left to the caller, which also divides ``slope_error_out`` by ``1 + gradient^2``.
        plane_out: plane height at the cell, ENU z; the rest as :class:`PlaneFit` (with
            ``slope_error_out`` before that division).
    """
    n0, n1 = height.shape
    size = 2 * half + 1
    area = float(size * size)
    scale = 1.0 / area
    f_scale = _F(1.0 / area)
    f_area = _F(area)
    f_ref = _F(ref)
    f_res = _F(resolution)
    f_degenerate = _F(1e-6 * resolution**4)
    f_two_area = _F(2.0 / area)
    f_neg_tol = _F(-tolerance)
    one = _F(1.0)
    zero = _F(0.0)
    nan = _F(np.nan)
    simd_cols = n1 - n1 % 4
    has_top = top.shape[0] > 0
    # Per cell: its mask and single-precision terms, kept for the output row.
    observed = np.zeros((n0, n1), np.bool_)
    zf = np.zeros((n0, n1), _F)
    varf = np.zeros((n0, n1), _F)
    x_of = np.empty(n0, _F)
    y_of = np.empty(n1, _F)
    for i in range(n0):
        x_of[i] = (_F(i) - _F(n0 // 2)) * f_res
    for j in range(n1):
        y_of[j] = (_F(j) - _F(n1 // 2)) * f_res
    # Ring of the last `size` rows' row sums (interleaved channels, double; the observed
    # count too, whose sums are whole numbers and so exact in any order), the column sums.
    nc = _CHANNELS
    ring = np.zeros((size, n1 * nc))
    col = np.zeros(n1 * nc)
    padded = np.zeros((n1 + 2 * half) * nc)
    sums = np.empty(n1 * nc)  # the window sums of the output row

    # The column sums start with the size - 1 rows above the first output row.
    for r in range(-half, half):
        slot = (r + size) % size
        _load(height, variance, cell_variance, r, x_of, y_of, f_ref, half, size, padded,
              observed, zf, varf, ring[slot])
        row = ring[slot]
        for k in range(n1 * nc):
            col[k] += row[k]
    for i in range(n0):
        enter = (i + half) % size
        _load(height, variance, cell_variance, i + half, x_of, y_of, f_ref, half, size,
              padded, observed, zf, varf, ring[enter])
        entering = ring[enter]
        leaving = ring[(i - half + size) % size]
        for k in range(n1 * nc):
            s0 = col[k] + entering[k]
            sums[k] = s0
            col[k] = s0 - leaving[k]
        x = x_of[i]
        for j in range(n1):
            cnt = sums[j * nc + 11]
            # OpenCV scales the mask's counts in single precision four columns at a time
            # and the columns left over in double precision.
            frac = _F(cnt) * f_scale if j < simd_cols else _F(cnt * scale)
            sw = _F(sums[j * nc + 0] * scale)
            bx = _F(sums[j * nc + 1] * scale)
            by = _F(sums[j * nc + 2] * scale)
            bz = _F(sums[j * nc + 3] * scale)
            inv = one / sw
            neg_mx = -(bx * inv)
            neg_my = -(by * inv)
            neg_mz = -(bz * inv)
            cxx = _fma(bx, neg_mx, _F(sums[j * nc + 4] * scale))
            cxy = _fma(bx, neg_my, _F(sums[j * nc + 5] * scale))
            cyy = _fma(by, neg_my, _F(sums[j * nc + 6] * scale))
            cxz = _fma(bx, neg_mz, _F(sums[j * nc + 7] * scale))
            cyz = _fma(by, neg_mz, _F(sums[j * nc + 8] * scale))
            czz = _fma(bz, neg_mz, _F(sums[j * nc + 9] * scale))
            det = cxx * cyy - cxy * cxy
            count = frac * f_area
            failed = not (count > _F(2.5) and det > (sw * sw) * f_degenerate)
            inv_det = nan if failed else one / det
            b = (cyy * cxz - cxy * cyz) * inv_det
            c = (cxx * cyz - cxy * cxz) * inv_det
            residual = ((czz - b * cxz) - c * cyz) * inv
            noise_var = frac * inv
            inv_weight = inv * f_scale
            plane = (neg_mx + x) * b + c * (neg_my + y_of[j]) - neg_mz
            spread = _nan_max(cxx + cyy, _F(1e-30))
            slope_error_out[i, j] = np.sqrt(f_two_area / spread)
            roughness_out[i, j] = np.sqrt(_nan_max(residual - noise_var, zero))
            z = zf[i, j]
            var = varf[i, j]
            seen = observed[i, j]
            step = abs(z - plane)
            step_error = np.sqrt(var + inv_weight)
            if has_top:
                top_step = (_F(top[i, j]) - f_ref) - plane
                top_error = np.sqrt(_fma(var, _F(3.0), inv_weight))
                if seen and _fma(top_error, f_neg_tol, top_step) > _fma(
                    step_error, f_neg_tol, step
                ):
                    step = top_step
                    step_error = top_error
            sigma = np.sqrt(_F(sums[j * nc + 10] * scale) / frac)
            if failed:
                roughness_error_out[i, j] = nan
                step_error = nan
                sigma = nan
            else:
                roughness_error_out[i, j] = (
                    np.sqrt(_F(2.0) / _nan_max(count - _F(3.0), one)) * noise_var
                )
            if not seen:
                step = nan
                step_error = nan
            b_out[i, j] = b
            c_out[i, j] = c
            plane_out[i, j] = plane + f_ref
            step_out[i, j] = step
            step_error_out[i, j] = step_error
            sigma_out[i, j] = sigma
            fraction_out[i, j] = min(max(frac, zero), one)
