"""Ray / height-field intersection, vectorised over rays."""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from sitl.terrain import Terrain

# Bisection steps refining the march step that crossed the surface (then one secant step):
# the bracket shrinks to 1/64 of a march step before the linear interpolation.
_BISECTIONS = 6


class _PatchSampler:
    """Bilinear heights from a contiguous copy of the grid window the rays can reach
    (small enough to stay in cache, unlike gathers from the whole grid)."""

    def __init__(self, terrain: Terrain, rows: slice, cols: slice) -> None:
        self.patch = np.ascontiguousarray(terrain.grid[rows, cols], dtype=np.float64)
        self.ny, self.nx = self.patch.shape
        self.flat = self.patch.reshape(-1)
        self.x0 = terrain.origin[0] + cols.start * terrain.cell_size
        self.y0 = terrain.origin[1] + rows.start * terrain.cell_size
        self.inv = 1.0 / terrain.cell_size

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        nx, ny = self.nx, self.ny
        fx = np.clip((x - self.x0) * self.inv, 0.0, nx - 1.000001)
        fy = np.clip((y - self.y0) * self.inv, 0.0, ny - 1.000001)
        j = fx.astype(np.intp)
        i = fy.astype(np.intp)
        tx = fx - j
        ty = fy - i
        k = i * nx + j
        g = self.flat
        h00 = g.take(k)
        h01 = g.take(k + 1)
        h10 = g.take(k + nx)
        h11 = g.take(k + nx + 1)
        top = h00 + tx * (h01 - h00)
        return top + ty * (h10 + tx * (h11 - h10) - top)


class BlockMax:
    """Highest ground near each block of ``block`` x ``block`` cells: the maximum over the
    block and its eight neighbours, so a point anywhere in a block has no ground above
    that value within ``block * cell_size`` metres. Lets rays skip empty space."""

    def __init__(self, terrain: Terrain, block: int = 8) -> None:
        g = terrain.grid
        ny, nx = g.shape
        by, bx = -(-ny // block), -(-nx // block)
        padded = np.pad(g, ((0, by * block - ny), (0, bx * block - nx)), mode="edge")
        coarse = padded.reshape(by, block, bx, block).max(axis=(1, 3))
        self.values = ndimage.maximum_filter(coarse, size=3, mode="nearest").astype(np.float64)
        self.flat = self.values.reshape(-1)
        self.shape = (by, bx)
        # Reach of a safe sideways jump: one block, less the half cell on each side over
        # which bilinear heights borrow from the next block.
        self.size = (block - 1) * terrain.cell_size
        self.block_size = block * terrain.cell_size
        # Block (0, 0) starts half a cell before cell (0, 0)'s centre.
        self.x0 = terrain.origin[0] - terrain.cell_size / 2
        self.y0 = terrain.origin[1] - terrain.cell_size / 2

    def __call__(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        j = np.clip((x - self.x0) / self.block_size, 0, self.shape[1] - 1).astype(np.intp)
        i = np.clip((y - self.y0) / self.block_size, 0, self.shape[0] - 1).astype(np.intp)
        return self.flat.take(i * self.shape[1] + j)


def cast_rays(
    terrain: Terrain,
    origin: np.ndarray,
    directions: np.ndarray,
    t_max: float = np.inf,
    step: float | None = None,
    block_max: BlockMax | None = None,
) -> np.ndarray:
    """Ray parameter of each ray's first hit on the terrain surface.

    All rays are marched together: each advances in steps that move it at most ``step``
    metres horizontally (default: the cell size, so no cell is skipped) and at most 1 m
    vertically, from where it descends below the highest ground it can reach to where it
    reaches the lowest; where a :class:`BlockMax` shows open air below the ray it jumps
    down to that level at once. The step that crosses the surface is refined by bisection
    and a final linear interpolation. Rays that finished are dropped from the march.

    Args:
        terrain: the height field.
        origin: (3,) ray origin, ENU metres (above the ground).
        directions: (N, 3) ray directions (any length; the result is in their units).
        t_max: rays not hitting before this parameter report NaN.
        step: horizontal march step (m).
        block_max: empty-space bounds of ``terrain`` (build once per terrain and reuse).

    Returns:
        (N,) float64 parameter t of the hit point ``origin + t * direction``; NaN for no hit
        (rays pointing up or level, hits beyond ``t_max``, origin under the ground).
    """
    origin = np.asarray(origin, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    result = np.full(len(d), np.nan)
    down = d[:, 2] < -1e-12
    if not down.any():
        return result
    step = terrain.cell_size if step is None else float(step)
    ox, oy, oz = origin
    # Bound the heights the rays can meet: the rays' footprint at the world's lowest level,
    # then the lowest and highest ground under that footprint (and the camera).
    drop = oz - float(terrain.grid.min())
    if drop <= 0:
        return result
    idx = np.flatnonzero(down)
    dx, dy, dz = d[idx, 0], d[idx, 1], d[idx, 2]
    t_floor = drop / -dz
    foot_x = ox + t_floor * dx
    foot_y = oy + t_floor * dy
    pad = 2 * terrain.cell_size
    rows, cols = terrain.window(
        (
            min(foot_x.min(), ox) - pad,
            max(foot_x.max(), ox) + pad,
            min(foot_y.min(), oy) - pad,
            max(foot_y.max(), oy) + pad,
        )
    )
    ny, nx = terrain.shape
    # Keep at least 2 x 2 cells (a footprint off the grid uses the edge cells' values).
    r0 = min(max(rows.start, 0), ny - 2)
    c0 = min(max(cols.start, 0), nx - 2)
    rows = slice(r0, max(rows.stop, r0 + 2))
    cols = slice(c0, max(cols.stop, c0 + 2))
    height = _PatchSampler(terrain, rows, cols)
    h_lo, h_hi = float(height.patch.min()), float(height.patch.max())
    if oz <= h_lo:
        return result
    # March each ray from the level of the highest ground down to the lowest.
    t_start = np.maximum(0.0, (oz - h_hi) / -dz)
    t_end = (oz - h_lo) / -dz
    dt = np.minimum(step / np.maximum(np.hypot(dx, dy), 1e-12), 1.0 / -dz)
    out = np.full(len(idx), np.nan)

    # Per-ray state of the rays still marching, compacted as rays finish.
    live = np.arange(len(idx))
    t = t_start
    f = oz + t * dz - height(ox + t * dx, oy + t * dy)
    lo_t, hi_t, lo_f, hi_f, who = [], [], [], [], []
    at_start = f <= 0  # under an overhang-free surface only if the camera is inside it
    out[at_start] = t[at_start]
    keep = ~at_start
    live, t, f = live[keep], t[keep], f[keep]
    ldx, ldy, ldz, ldt, lend = dx[live], dy[live], dz[live], dt[live], t_end[live]
    lhor = np.hypot(ldx, ldy)
    while live.size:
        advance = ldt
        if block_max is not None:
            z = oz + t * ldz
            clear = z - block_max(ox + t * ldx, oy + t * ldy)
            # Safe jump: down to the highest nearby ground, or one block sideways.
            jump = np.minimum(clear / -ldz, block_max.size / np.maximum(lhor, 1e-12))
            advance = np.maximum(ldt, jump)
        t_next = np.minimum(t + advance, lend)
        f_next = oz + t_next * ldz - height(ox + t_next * ldx, oy + t_next * ldy)
        crossed = f_next <= 0
        if crossed.any():
            who.append(live[crossed])
            lo_t.append(t[crossed])
            hi_t.append(t_next[crossed])
            lo_f.append(f[crossed])
            hi_f.append(f_next[crossed])
        # At the lowest ground every ray has crossed; the far clip stops the others.
        go_on = ~crossed & (t_next < lend) & (t_next < t_max)
        if go_on.all():
            t, f = t_next, f_next
            continue
        live, t, f = live[go_on], t_next[go_on], f_next[go_on]
        ldx, ldy, ldz, ldt, lend = ldx[go_on], ldy[go_on], ldz[go_on], ldt[go_on], lend[go_on]
        lhor = lhor[go_on]
    if who:
        k = np.concatenate(who)
        a, b = np.concatenate(lo_t), np.concatenate(hi_t)
        fa, fb = np.concatenate(lo_f), np.concatenate(hi_f)
        kx, ky, kz = dx[k], dy[k], dz[k]
        for _ in range(_BISECTIONS):
            mid = 0.5 * (a + b)
            fm = oz + mid * kz - height(ox + mid * kx, oy + mid * ky)
            below = fm <= 0
            b = np.where(below, mid, b)
            fb = np.where(below, fm, fb)
            a = np.where(below, a, mid)
            fa = np.where(below, fa, fm)
        # Secant within the final bracket (fa > 0 >= fb).
        denom = fa - fb
        frac = np.where(denom > 0, fa / np.where(denom > 0, denom, 1.0), 1.0)
        out[k] = a + np.clip(frac, 0.0, 1.0) * (b - a)
    out[out > t_max] = np.nan
    result[idx] = out
    return result
