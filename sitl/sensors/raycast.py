"""Ray / height-field intersection.

:func:`cast_rays` marches any set of rays, vectorised over rays (the LiDAR's, and the
fine-step reference); :func:`cast_pinhole_rays` (or :meth:`PinholeRays.cast`, keeping what
it derives from the rays between frames) renders a downward pinhole camera's image many
times faster, from bounds on the ground a :class:`HeightBounds` pyramid gives per image tile
(the march itself is compiled: :mod:`sitl.sensors.march`); :func:`coarse_terrain` gives the
mean-height levels of detail a distant camera renders.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from sitl.sensors import march
from sitl.sensors.region import GroundRegion, pixels_needed, tiles_needed
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


# --- Fast pinhole rendering: bracket each ray between bounds from a min/max pyramid, then
# march and refine each ray in compiled code (sitl.sensors.march). ----------------------

# Tile sizes (px) of the image-space hierarchy and bound iterations at each.
_TILE_PASSES = ((16, 3), (4, 2))
# A ray point this close (m, vertically) to the ground is the hit.
_CLOSE = 5e-4


class HeightBounds:
    """Highest and lowest ground of the bilinear height field over square blocks of cells:
    a max and a min pyramid (maximum mipmap) built once per terrain.

    Level 0 holds, per cell (the square between four neighbouring cell centres), the max and
    min of its four corners, which bound the bilinear surface over the cell exactly; level
    ``L`` pools 2 x 2 nodes of level ``L - 1``, so a node covers 2**L x 2**L cells. Outside
    the grid the surface continues with edge values, which the edge cells bound too.

    Args:
        terrain: the height field.
    """

    def __init__(self, terrain: Terrain) -> None:
        g = terrain.grid
        rows, cols = [g.shape[0] - 1], [g.shape[1] - 1]
        while max(rows[-1], cols[-1]) > 1:  # sides halved, odd ones rounded up
            rows.append((rows[-1] + 1) // 2)
            cols.append((cols[-1] + 1) // 2)
        rows, cols = np.array(rows, dtype=np.intp), np.array(cols, dtype=np.intp)
        sizes = rows * cols
        self.levels = len(rows)
        self.width = cols
        self.offset = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(np.intp)
        # Every level in one flat array (one pass over the grid, then over each level).
        self.high = np.empty(int(sizes.sum()), dtype=g.dtype)
        self.low = np.empty_like(self.high)
        march.build_pyramid(g, rows, cols, self.offset, self.high, self.low)
        self.scale = np.ldexp(1.0, -np.arange(self.levels))
        self.cells = (g.shape[0] - 1, g.shape[1] - 1)
        self.top = float(self.high[-1])
        self.bottom = float(self.low[-1])
        self.grid = g
        self.origin = terrain.origin
        self.cell_size = terrain.cell_size
        # What the compiled march reads of the pyramid (sitl.sensors.march.box_bounds).
        self.pyramid = (self.high, self.low, self.width, self.offset, self.scale,
                        self.levels, self.cells[1], self.cells[0])

    def region(self, u0, u1, v0, v1) -> tuple[np.ndarray, np.ndarray]:
        """Bounds (high, low) on the ground over boxes ``[u0, u1] x [v0, v1]`` given in
        cell-centre coordinates (column u, row v; u = (x - origin x) / cell size). Arrays
        of any one shape; the bounds are float32, conservative (a box reads at most 2 x 2
        nodes of the finest level whose nodes are at least as wide as it)."""
        boxes = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (u0, u1, v0, v1)))
        high = np.empty(boxes[0].shape, dtype=np.float32)
        low = np.empty_like(high)
        march.boxes_bounds(self.pyramid, *(np.ascontiguousarray(b).ravel() for b in boxes),
                           high.reshape(-1), low.reshape(-1))
        return high, low


def coarse_terrain(terrain: Terrain, level: int) -> Terrain:
    """The terrain at a coarser level of detail: the mean height of each block of
    ``2**level`` x ``2**level`` cells (edge cells repeated to fill the last blocks), as a
    grid of ``2**level`` times the cell size centred on the blocks. Level 0 is
    ``terrain`` itself. A planar terrain stays the same plane."""
    if level <= 0:
        return terrain
    grid = terrain.grid
    for _ in range(level):
        grid = march.pool_mean(grid)
    n = 2**level
    shift = (n - 1) / 2 * terrain.cell_size
    origin = (terrain.origin[0] + shift, terrain.origin[1] + shift)
    return Terrain(grid, n * terrain.cell_size, origin=origin, kind=terrain.kind)


class PinholeRays:
    """The ray directions of a pinhole camera's pixels, with what the caster derives from
    them alone (kept between frames: build once per camera orientation and reuse).

    Args:
        directions: (H, W, 3) ray direction of every pixel (any length; cast results are in
            their units), all pointing down (z < 0), e.g. with unit optical-axis component
            so the ray parameter is the depth. Raises ValueError otherwise.
    """

    def __init__(self, directions: np.ndarray) -> None:
        d = np.asarray(directions)
        if d.ndim != 3 or d.shape[2] != 3:
            raise ValueError("directions: need (H, W, 3) rays all pointing down (z < 0)")
        self._set(d[..., 0], d[..., 1], d[..., 2])

    @classmethod
    def from_components(cls, dx, dy, dz) -> PinholeRays:
        """The same from the three (H, W) component arrays of the directions."""
        rays = cls.__new__(cls)
        rays._set(dx, dy, dz)
        return rays

    def _set(self, dx, dy, dz) -> None:
        dx, dy, dz = (np.ascontiguousarray(c, dtype=np.float32) for c in (dx, dy, dz))
        if dx.ndim != 2 or not (dx.shape == dy.shape == dz.shape) or not np.all(dz < 0):
            raise ValueError("directions: need (H, W, 3) rays all pointing down (z < 0)")
        self.shape = dx.shape
        self.dx, self.dy, self.dz = dx, dy, dz
        self._per_cell: dict[float, dict] = {}

    def _derived(self, cell_size: float) -> dict:
        """Per-cell-size arrays: flat float32 (du, dv, dz, 1 / horizontal speed) in cells
        per unit t, and per image tile the corner rays' extremes (float64)."""
        got = self._per_cell.get(cell_size)
        if got is not None:
            return got
        scale = np.float32(1.0 / cell_size)
        du, dv, dz = self.dx * scale, self.dy * scale, self.dz
        height, width = self.shape
        tiles = []
        for tile, passes in _TILE_PASSES:
            # The tile's rays lie between its four corner rays (the components are affine
            # in the pixel coordinates; at any t >= 0 the footprint is within the corners'
            # bounding box).
            r0 = np.arange(0, height, tile)
            c0 = np.arange(0, width, tile)
            r1 = np.minimum(r0 + tile - 1, height - 1)
            c1 = np.minimum(c0 + tile - 1, width - 1)
            corners = [(a, b) for a in (r0, r1) for b in (c0, c1)]
            ext = []
            for comp in (du, dv, dz):
                at = [comp.take(a, axis=0).take(b, axis=1) for a, b in corners]
                lo = np.minimum(np.minimum(at[0], at[1]), np.minimum(at[2], at[3]))
                hi = np.maximum(np.maximum(at[0], at[1]), np.maximum(at[2], at[3]))
                ext += [lo.astype(np.float64), hi.astype(np.float64)]
            tiles.append((tile, passes, np.stack(ext)))
        hor = np.hypot(du, dv)
        np.maximum(hor, np.float32(1e-6), out=hor)
        finest = _TILE_PASSES[-1][0]
        got = {
            "du": du.ravel(),
            "dv": dv.ravel(),
            "dz": dz.ravel(),
            "inv_hor": np.divide(np.float32(1.0), hor.ravel()),
            "nadir": bool(np.all(dz == -1.0)),  # ray height oz - t: one product less
            "all": np.ones(height * width, dtype=bool),
            # The finest tile of each pixel (flat indices; the march reads its bracket).
            "tile_of": ((np.arange(height) // finest)[:, None] * (-(-width // finest))
                        + np.arange(width) // finest).ravel(),
            "tiles": tiles,
        }
        self._per_cell[cell_size] = got
        return got

    def cast(
        self,
        bounds: HeightBounds,
        origin: np.ndarray,
        t_max: float = np.inf,
        step: float | None = None,
        tolerance: float = _CLOSE,
    ) -> np.ndarray:
        """Ray parameter of every pixel's first hit on ``bounds``' terrain; see
        :func:`cast_pinhole_rays`. The refinement stops where the ray point is within
        ``tolerance`` (m, vertically) of the ground. Returns (H, W) float32, NaN beyond
        ``t_max``."""
        return _cast(bounds, self, origin, t_max, step, np.float32(tolerance))[0]

    def cast_within(
        self,
        bounds: HeightBounds,
        origin: np.ndarray,
        region: GroundRegion,
        depth_error: tuple = (np.float32(0.0), np.float32(0.0)),
        t_max: float = np.inf,
        step: float | None = None,
        tolerance: float = _CLOSE,
    ) -> tuple[np.ndarray, np.ndarray | None]:
        """:meth:`cast` for only the image tiles whose points can matter to ``region``
        (:func:`sitl.sensors.region.tiles_needed`, whose ``depth_error`` bounds the
        measured depths about the true ones). Returns the (H, W) float32 parameters,
        NaN where not rendered, and the (H, W) bool mask of the rendered pixels (None when
        every pixel was)."""
        return _cast(bounds, self, origin, t_max, step, np.float32(tolerance),
                     (region, depth_error))


def cast_pinhole_rays(
    bounds: HeightBounds,
    origin: np.ndarray,
    directions: np.ndarray,
    t_max: float = np.inf,
    step: float | None = None,
) -> np.ndarray:
    """Ray parameter of the first hit on the terrain of every pixel's ray of a pinhole
    camera looking down.

    Image-space hierarchy: tiles of pixels (then single rays) keep a bracket ``[lo, hi]``
    of the ray parameter, ``lo`` before any of the tile's rays can meet the ground (they
    are above the highest ground under the tile's footprint) and ``hi`` after all of them
    have (below the lowest), narrowed with :meth:`HeightBounds.region` over the footprint
    between the two. A ray whose bracket spans more than ``step`` horizontally is then
    marched through it ``step`` at a time (so no cell is skipped and the hit is the first);
    the crossing is refined by regula falsi with bilinear heights computed as OpenCV's
    ``remap`` computes them. Each ray is one compiled loop (:mod:`sitl.sensors.march`).

    Args:
        bounds: the terrain's :class:`HeightBounds` (build once per terrain).
        origin: (3,) camera centre, ENU metres.
        directions: (H, W, 3) ray direction of every pixel (any length; the result is in
            their units), all pointing down (z < 0), e.g. with unit optical-axis component
            so the parameter is the depth. Raises ValueError otherwise. A camera rendering
            many frames keeps a :class:`PinholeRays` of them instead.
        t_max: hits beyond this parameter report NaN.
        step: horizontal march step (m); default: the cell size.

    Returns:
        (H, W) float32 parameter of the hit point ``origin + t * direction``; NaN beyond
        ``t_max``.
    """
    return _cast(bounds, PinholeRays(directions), origin, t_max, step, np.float32(_CLOSE))[0]


def _cast(bounds, rays: PinholeRays, origin, t_max, step, close, region=None):
    """(t, rendered): see :meth:`PinholeRays.cast_within`; ``region`` is None or
    (:class:`GroundRegion`, depth error)."""
    ox, oy, oz = (float(c) for c in origin)
    height, width = rays.shape
    cs = bounds.cell_size
    per = rays._derived(cs)
    # Cell-centre coordinates: u = u_o + t * du (columns), v = v_o + t * dv (rows).
    u_o = (ox - bounds.origin[0]) / cs
    v_o = (oy - bounds.origin[1]) / cs
    lo = hi = np.empty((0, 0))
    tile_prev = 0
    for tile, passes, ext in per["tiles"]:
        lo, hi = march.tile_brackets(bounds.pyramid, ext, lo, hi, tile_prev // tile, passes,
                                     (u_o, v_o, oz), (bounds.top, bounds.bottom))
        tile_prev = tile
    step = per["inv_hor"] if step is None else per["inv_hor"] * np.float32(float(step) / cs)
    rendered = None
    pick = per["all"]
    if region is not None:
        ext = per["tiles"][-1][2]
        need = tiles_needed(region[0], tuple(ext[:4]), lo, hi, (u_o, v_o),
                            (bounds.origin[0], bounds.origin[1], cs), tile_prev, region[1])
        if not need.all():
            rendered = pixels_needed(region[0], need, tile_prev, (height, width))
            pick = rendered.reshape(-1)
    t = np.full(height * width, np.nan, dtype=np.float32)
    march.march_rays(bounds.grid, bounds.pyramid,
                     (np.float32(u_o), np.float32(v_o), np.float32(oz)), per["nadir"], close,
                     lo.astype(np.float32).ravel(), hi.astype(np.float32).ravel(),
                     per["tile_of"], pick, per["du"], per["dv"],
                     per["dz"], step, t)
    t = t.reshape(height, width)
    if t_max < np.inf:
        t[t > t_max] = np.nan
    return t, rendered
