"""Compiled kernels of the pinhole camera's ray march (:func:`sitl.sensors.raycast.
cast_pinhole_rays`): the tile brackets from the height-bounds pyramid, then per ray the march,
the thin-feature check, the skips over open air and the regula falsi refinement.

They compute what the array version computed, operation for operation and in the same
precision (float64 for the tile brackets, float32 per ray), so the depths are the same bit
for bit: numba compiles without fast-math, so LLVM neither reorders nor fuses these
operations. The one fused multiply-add is deliberate: the bilinear heights are those of
OpenCV's ``remap`` (INTER_LINEAR, BORDER_REPLICATE) on float32, whose kernels interpolate
with fused multiply-adds ``p00 + a (p01 - p00)`` on cell-relative coordinates, and
:func:`bilinear` does the same.

Compiled on first use and cached beside this file (``cache=True``).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

# Steps a marching ray may skip at once over open air.
SKIP = 8
# Most regula falsi (Illinois) iterations on a ray's final bracket.
FALSI = 16

_F0 = np.float32(0.0)
_F1 = np.float32(1.0)
_HALF = np.float32(0.5)
_TINY = np.float32(1e-30)
_SKIP_F = np.float32(SKIP)
_EIGHTH = np.float32(8.0)


@intrinsic
def _fma(typingctx, a, b, c):
    """a * b + c rounded once (float32)."""
    sig = types.float32(types.float32, types.float32, types.float32)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


@intrinsic
def _floor(typingctx, x):
    """Largest integral value not above x (float32), as one instruction (numba's
    math.floor calls a helper function)."""
    sig = types.float32(types.float32)

    def codegen(context, builder, signature, args):
        fn = builder.module.declare_intrinsic("llvm.floor", [args[0].type])
        return builder.call(fn, args)

    return sig, codegen


@intrinsic
def _bits(typingctx, x):
    """The IEEE 754 bits of a float64 as an int64."""
    sig = types.int64(types.float64)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return sig, codegen


@njit(cache=True, nogil=True, _nrt=False, inline="always")
def _exponent(x):
    """The exponent of ``math.frexp(x)`` (x = m 2**e, 0.5 <= |m| < 1; 0 for zero, inf,
    NaN) from the bits (math.frexp calls the C library)."""
    e = (_bits(x) >> 52) & 0x7FF
    if e == 0x7FF:
        return 0
    if e == 0:
        return math.frexp(x)[1]  # zero or subnormal
    return e - 1022


@njit(cache=True, nogil=True, _nrt=False)
def bilinear(grid, u, v):
    """Bilinear height of ``grid`` (float32) at cell-centre coordinates (u column, v row),
    edge values beyond it: OpenCV's remap arithmetic (floor, fractions, two fused blends
    along u, one along v)."""
    ny, nx = grid.shape
    fu = _floor(u)
    fv = _floor(v)
    iu = int(fu)
    iv = int(fv)
    au = u - fu  # = u - float(iu): the ray coordinates stay far below 2**24 cells
    av = v - fv
    if 0 <= iu < nx - 1 and 0 <= iv < ny - 1:
        p00 = grid[iv, iu]
        p01 = grid[iv, iu + 1]
        p10 = grid[iv + 1, iu]
        p11 = grid[iv + 1, iu + 1]
    else:
        u0 = min(max(iu, 0), nx - 1)
        u1 = min(max(iu + 1, 0), nx - 1)
        v0 = min(max(iv, 0), ny - 1)
        v1 = min(max(iv + 1, 0), ny - 1)
        p00 = grid[v0, u0]
        p01 = grid[v0, u1]
        p10 = grid[v1, u0]
        p11 = grid[v1, u1]
    h0 = _fma(au, p01 - p00, p00)
    h1 = _fma(au, p11 - p10, p10)
    return _fma(av, h1 - h0, h0)


@njit(cache=True, nogil=True, _nrt=False, inline="always")
def box_bounds(high, low, width, offset, scale, levels, zero, top_u, top_v, u0, u1, v0, v1):
    """(highest, lowest) ground over the box ``[u0, u1] x [v0, v1]`` (cell-centre
    coordinates) from the pyramid of :class:`~sitl.sensors.raycast.HeightBounds`: the 2 x 2
    nodes of the finest level whose nodes are at least as wide as the box. ``zero``,
    ``top_u`` and ``top_v`` (the clip range) have the coordinates' type, which the span's
    subtraction is computed in."""
    u0 = zero if u0 < zero else (top_u if u0 > top_u else u0)
    u1 = zero if u1 < zero else (top_u if u1 > top_u else u1)
    v0 = zero if v0 < zero else (top_v if v0 > top_v else v0)
    v1 = zero if v1 < zero else (top_v if v1 > top_v else v1)
    span_u = u1 - u0
    span_v = v1 - v0
    # Level ceil(log2(span)), or one coarser when the span is a power of two.
    level = _exponent(np.float64(span_u if span_u >= span_v else span_v))
    level = min(max(level, 0), levels - 1)
    s = scale[level]
    w = width[level]
    base = offset[level]
    r0 = int(v0 * s) * w + base
    r1 = int(v1 * s) * w + base
    c0 = int(u0 * s)
    c1 = int(u1 * s)
    top = max(max(high[r0 + c0], high[r0 + c1]), max(high[r1 + c0], high[r1 + c1]))
    bottom = min(min(low[r0 + c0], low[r0 + c1]), min(low[r1 + c0], low[r1 + c1]))
    return top, bottom


@njit(cache=True, nogil=True)
def build_pyramid(grid, rows, cols, offset, high, low):
    """Fill the flat level arrays of :class:`~sitl.sensors.raycast.HeightBounds`: level 0
    the max and min of each cell's four corners, each next level the 2 x 2 nodes of the one
    before (the last row or column of an odd side pooled alone)."""
    h0, w0 = rows[0], cols[0]
    for i in range(h0):
        for j in range(w0):
            a, b = grid[i, j], grid[i + 1, j]
            c, d = grid[i, j + 1], grid[i + 1, j + 1]
            high[i * w0 + j] = max(max(a, b), max(c, d))
            low[i * w0 + j] = min(min(a, b), min(c, d))
    for level in range(1, rows.size):
        ph, pw, po = rows[level - 1], cols[level - 1], offset[level - 1]
        h, w, o = rows[level], cols[level], offset[level]
        for i in range(h):
            r0 = po + 2 * i * pw
            r1 = po + min(2 * i + 1, ph - 1) * pw
            for j in range(w):
                c0, c1 = 2 * j, min(2 * j + 1, pw - 1)
                high[o + i * w + j] = max(max(high[r0 + c0], high[r1 + c0]),
                                          max(high[r0 + c1], high[r1 + c1]))
                low[o + i * w + j] = min(min(low[r0 + c0], low[r1 + c0]),
                                         min(low[r0 + c1], low[r1 + c1]))


@njit(cache=True, nogil=True)
def pool_mean(grid):
    """The mean of each 2 x 2 block of ``grid`` (float64; an odd side's last row or column
    repeated to fill its blocks) as numpy's ``mean(axis=(1, 3))`` of the blocks computes it:
    in float64, the two pairs along a row summed first, then the pairs' sums, over 4."""
    ny, nx = grid.shape
    out = np.empty(((ny + 1) // 2, (nx + 1) // 2))
    for i in range(out.shape[0]):
        r0, r1 = 2 * i, min(2 * i + 1, ny - 1)
        for j in range(out.shape[1]):
            c0, c1 = 2 * j, min(2 * j + 1, nx - 1)
            top = np.float64(grid[r0, c0]) + np.float64(grid[r0, c1])
            bottom = np.float64(grid[r1, c0]) + np.float64(grid[r1, c1])
            out[i, j] = (top + bottom) / 4.0
    return out


@njit(cache=True, nogil=True)
def boxes_bounds(pyramid, u0, u1, v0, v1, high_out, low_out):
    """:func:`box_bounds` of every box of the flat float64 arrays, into ``high_out`` and
    ``low_out``."""
    high, low, width, offset, scale, levels, ncx, ncy = pyramid
    for k in range(u0.size):
        high_out[k], low_out[k] = box_bounds(high, low, width, offset, scale, levels, 0.0,
                                             ncx - 1e-3, ncy - 1e-3, u0[k], u1[k], v0[k], v1[k])


@njit(cache=True, nogil=True)
def tile_brackets(pyramid, ext, parent_lo, parent_hi, ratio, passes, start, extremes):
    """Per image tile, the bracket ``[lo, hi]`` (float64) of its rays' parameters between
    leaving the highest and reaching the lowest ground under its footprint, narrowed
    ``passes`` times from the parent tiles' brackets (``ratio`` tiles per parent side; no
    parent: from the terrain's extremes).

    Args:
        pyramid: (high, low, width, offset, scale, levels, cells x, cells y) of the bounds.
        ext: (6, rows, cols) float64: du_min, du_max, dv_min, dv_max, z_lo, z_hi per tile.
        parent_lo, parent_hi: the parent tiles' brackets (ignored when ``ratio`` is 0).
        start: (u, v, z) of the camera, float64.
        extremes: (top, bottom) of the whole terrain.
    """
    high, low, width, offset, scale, levels, ncx, ncy = pyramid
    u_o, v_o, oz = start
    top_all, bottom_all = extremes
    top_u = ncx - 1e-3
    top_v = ncy - 1e-3
    rows, cols = ext.shape[1], ext.shape[2]
    lo_out = np.empty((rows, cols))
    hi_out = np.empty((rows, cols))
    for i in range(rows):
        for j in range(cols):
            if ratio == 0:
                lo_out[i, j] = max(0.0, (oz - top_all) / -ext[4, i, j])
                hi_out[i, j] = (oz - bottom_all) / -ext[5, i, j]
            else:
                lo_out[i, j] = parent_lo[i // ratio, j // ratio]
                hi_out[i, j] = parent_hi[i // ratio, j // ratio]
    # Pass by pass over all the tiles (not tile by tile): a tile's passes are a chain of
    # dependent lookups and divisions, the tiles of one pass are independent.
    for _ in range(passes):
        for i in range(rows):
            for j in range(cols):
                du_min, du_max = ext[0, i, j], ext[1, i, j]
                dv_min, dv_max = ext[2, i, j], ext[3, i, j]
                lo, hi = lo_out[i, j], hi_out[i, j]
                u0 = u_o + min(du_min * lo, du_min * hi)
                u1 = u_o + max(du_max * lo, du_max * hi)
                v0 = v_o + min(dv_min * lo, dv_min * hi)
                v1 = v_o + max(dv_max * lo, dv_max * hi)
                top, bottom = box_bounds(high, low, width, offset, scale, levels, 0.0,
                                         top_u, top_v, u0, u1, v0, v1)
                lo = max(lo, (oz - top) / -ext[4, i, j])
                lo_out[i, j] = lo
                hi_out[i, j] = max(lo, min(hi, (oz - bottom) / -ext[5, i, j]))
    return lo_out, hi_out


@njit(cache=True, nogil=True, _nrt=False)
def _above(grid, start, nadir, t, du, dv, dz):
    """Height of the ray point at ``t`` above the ground (float32)."""
    u_o, v_o, oz = start
    h = bilinear(grid, t * du + u_o, t * dv + v_o)
    z = oz - t if nadir else t * dz + oz
    return z - h


@njit(cache=True, nogil=True, _nrt=False, inline="always")
def _top(pyramid, start, a, b, du, dv):
    """Highest ground under the ray's footprint between parameters ``a`` and ``b``."""
    high, low, width, offset, scale, levels, ncx, ncy = pyramid
    u_o, v_o, _ = start
    ua, ub = u_o + a * du, u_o + b * du
    va, vb = v_o + a * dv, v_o + b * dv
    top, _ = box_bounds(high, low, width, offset, scale, levels, _F0,
                        np.float32(ncx - 1e-3), np.float32(ncy - 1e-3),
                        min(ua, ub), max(ua, ub), min(va, vb), max(va, vb))
    return top


@njit(cache=True, nogil=True, _nrt=False)
def _secant(a, b, fa, fb):
    """Zero of the line through (a, fa) and (b, fb), fa > 0 >= fb, clipped to [a, b]."""
    frac = fa - fb
    if frac < _TINY:
        frac = _TINY
    frac = fa / frac
    if frac > _F1:
        frac = _F1
    return (b - a) * frac + a


@njit(cache=True, nogil=True, _nrt=False)
def _march_on(grid, pyramid, start, nadir, a, b, fa, fb, hi, du, dv, dz, step):
    """Go on marching a ray whose first step ``[a, b]`` (b < hi) stayed above the
    ground, a step at a time to its first crossing (skipping steps under which the ground
    stays below it, looking inside each step for features thinner than it): (a, b, f(a),
    f(b)) with f(a) > 0 >= f(b), or the last step's ends at ``hi`` (the far clip)."""
    oz = start[2]
    while True:
        # Ground rising above the ray between the step's ends (a wall or a rock edge
        # thinner than a step): where the ray at b is under the highest ground of the
        # cells the step crosses, the first eighth under ground ends the bracket.
        if oz + b * dz <= _top(pyramid, start, a, b, du, dv):
            span = b - a
            s_prev, f_prev = a, fa
            for k in range(1, 8):
                s = a + (np.float32(k) / _EIGHTH) * span
                fs = _above(grid, start, nadir, s, du, dv, dz)
                if fs <= 0:
                    return s_prev, s, f_prev, fs
                s_prev, f_prev = s, fs
        # The next step from the last one's end, over the open air first.
        a, fa = b, fb
        e = min(a + _SKIP_F * step, hi)
        new = min(max((oz - _top(pyramid, start, a, e, du, dv)) / -dz, a), e)
        if new > a:
            fa = _above(grid, start, nadir, new, du, dv, dz)
        a = new
        b = min(a + step, hi)
        fb = _above(grid, start, nadir, b, du, dv, dz)
        if not (fb > 0 and b < hi):
            return a, b, fa, fb


@njit(cache=True, nogil=True)
def march_rays(grid, pyramid, start, nadir, close, lo_tiles, hi_tiles, tile_of, pick, du, dv,
               dz, step, out):
    """Depth parameter of the rays of the pixels ``pick`` marks (flat bool) into ``out``
    (flat float32): each ray bracketed by its tile's ``[lo, hi]`` (flat float32 tile
    arrays; ``tile_of``: the tile of each pixel) and marched, then refined by regula
    falsi (Illinois) until the ray point is within ``close`` of the ground. The refinement
    runs on the rays not yet close together, and drops the close ones only when more than
    a quarter of them are (the array version's schedule, which decides how far each ray is
    refined)."""
    n = pick.size
    # The rays still refining, in pixel order: pixel, bracket, last point.
    live = np.empty(n, np.int64)
    a = np.empty(n, np.float32)
    b = np.empty(n, np.float32)
    fa = np.empty(n, np.float32)
    fb = np.empty(n, np.float32)
    c = np.empty(n, np.float32)
    fc = np.empty(n, np.float32)
    m = 0
    for p in range(n):
        if not pick[p]:
            continue
        q = tile_of[p]
        lo = lo_tiles[q]
        hi = hi_tiles[q]
        pdu, pdv, pdz, pstep = du[p], dv[p], dz[p], step[p]
        # March a step at a time (horizontally) from lo; a step reaching hi has crossed.
        ka = lo
        kfa = _above(grid, start, nadir, ka, pdu, pdv, pdz)
        kb = min(lo + pstep, hi)
        kfb = _above(grid, start, nadir, kb, pdu, pdv, pdz)
        if kfb > 0 and kb < hi:  # most rays cross in the first step
            ka, kb, kfa, kfb = _march_on(grid, pyramid, start, nadir, ka, kb, kfa, kfb, hi,
                                         pdu, pdv, pdz, pstep)
        if kfa <= 0:
            # Under ground at a (by the bilinear heights' rounding at a bound, or the
            # camera inside the terrain): a bracket [a, a] with f(a) > 0 pretended.
            kb, kfb, kfa = ka, kfa, _TINY
        t = _secant(ka, kb, kfa, kfb)
        ft = _above(grid, start, nadir, t, pdu, pdv, pdz)
        out[p] = t
        if abs(ft) > close:
            live[m] = p
            a[m], b[m], fa[m], fb[m], c[m], fc[m] = ka, kb, kfa, kfb, t, ft
            m += 1
    last = np.zeros(m, np.int8)  # which end the previous step replaced (+1: a, -1: b)
    for it in range(1, FALSI):
        if m == 0:
            break
        n_close = 0
        for k in range(m):
            p = live[k]
            # c replaces a where f(c) > 0, else b; Illinois: an end kept twice in a row has
            # its value halved.
            if fc[k] > 0:
                if last[k] > 0:
                    fb[k] = _HALF * fb[k]
                fa[k] = fc[k]
                a[k] = c[k]
                last[k] = 1
            else:
                if last[k] < 0:
                    fa[k] = _HALF * fa[k]
                fb[k] = fc[k]
                b[k] = c[k]
                last[k] = -1
            c[k] = _secant(a[k], b[k], fa[k], fb[k])
            fc[k] = _above(grid, start, nadir, c[k], du[p], dv[p], dz[p])
            out[p] = c[k]
            if abs(fc[k]) <= close:
                n_close += 1
        if it == FALSI - 1 or n_close == m:
            break
        if n_close > m // 4:
            kept = 0
            for k in range(m):
                if not abs(fc[k]) <= close:
                    live[kept], last[kept] = live[k], last[k]
                    a[kept], b[kept], fa[kept], fb[kept] = a[k], b[k], fa[k], fb[k]
                    c[kept], fc[kept] = c[k], fc[k]
                    kept += 1
            m = kept
