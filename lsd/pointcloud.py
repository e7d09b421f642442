"""Point-cloud plumbing for the LiDAR detector: cleaning, voxel-grid downsampling, the
horizontal column index used for neighbourhood queries, and the accumulator that decides when
an accumulated cloud is processed (Loureiro et al. 2021, sections 4.1-4.3).

Input clouds are ``(N, 3)`` float64 arrays of world points, ENU metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.spatial import cKDTree

MAX_COORDINATE = 1e8
"""m: a coordinate farther than this from the origin is not a point of a landing site (Earth
fixed frames stay within 6,400 km, UTM northings within 10,000 km); voxel and column indices
of such clouds would not fit their integers."""


def clean_points(points: np.ndarray) -> tuple[np.ndarray, int]:
    """Keep the rows of a cloud whose coordinates are finite and within MAX_COORDINATE.

    Args:
        points: ``(N, 3)`` array-like (any extra columns are dropped).

    Returns:
        ``(cloud, dropped)``: the ``(M, 3)`` float64 rows kept, and the number of rows
        dropped. A cloud of the wrong shape is dropped whole.
    """
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] < 3:
        return np.empty((0, 3)), int(arr.shape[0]) if arr.ndim >= 1 else 1
    arr = arr[:, :3]
    with np.errstate(invalid="ignore"):
        usable = (np.abs(arr) <= MAX_COORDINATE).all(axis=1)  # NaN compares False
    return np.ascontiguousarray(arr[usable]), int(arr.shape[0] - usable.sum())


_ROWS_PER_CALL = 1 << 16  # (centre, grid row) slices looked up at once by cylinders()
_SQUARE_ROWS = 12  # up to this many rows each side, candidates() covers a disc by a square

# Voxel keys (and the point index packed beside them) must fit one int64.
_KEY_BITS = 63


@dataclass(frozen=True)
class ColumnIndex:
    """Horizontal index of a cloud sorted by grid column: point ``i`` lies in column
    ``(kx, ky) = floor((x - origin) / cell)`` and ``keys[i] = kx * ny + ky`` is
    non-decreasing, so the points of a run of columns along y are one slice. It is the
    voxel grid's own sort order (our counterpart of the paper's octree, section 4.3).

    Attributes:
        keys: ``(N,)`` int64 column key of every point, non-decreasing.
        origin: ``(2,)`` x, y of the grid corner, metres.
        cell: column edge, metres.
        shape: ``(nx, ny)`` columns.
    """

    keys: np.ndarray
    origin: tuple[float, float]
    cell: float
    shape: tuple[int, int]

    @staticmethod
    def build(x: np.ndarray, y: np.ndarray, cell: float) -> tuple[ColumnIndex, np.ndarray]:
        """Index an unsorted cloud (``x``, ``y`` ``(N,)``): the index and the ``(N,)`` order
        that sorts the points by column (stable)."""
        if len(x) == 0:
            return ColumnIndex(np.empty(0, dtype=np.int64), (0.0, 0.0), cell, (1, 1)), np.empty(
                0, dtype=np.int64
            )
        lo = (float(x.min()), float(y.min()))
        inv = 1.0 / cell
        kx = ((x - lo[0]) * inv).astype(np.int64)
        ky = ((y - lo[1]) * inv).astype(np.int64)
        nx, ny = int(kx.max()) + 1, int(ky.max()) + 1
        keys = kx * ny + ky
        order = np.argsort(keys, kind="stable")
        return ColumnIndex(keys[order], lo, float(cell), (nx, ny)), order

    def candidates(self, centres: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
        """Points of the grid cells that cover a horizontal disc around each centre (a
        superset of the disc: whole cells along its edge).

        Args:
            centres: ``(S, 2)`` horizontal centres, metres.
            radius: disc radius, metres.

        Returns:
            ``(owner, index)``, both ``(P,)`` int64: centre and point of every candidate,
            contiguous per centre, centres in order, points in index order within a centre.
            Each grid row crossing a disc is one slice of the sorted keys (the disc's chord
            over the row bounds its y-range); one ``searchsorted`` finds both ends of every
            slice. No tree walk.
        """
        cell, inv = self.cell, 1.0 / self.cell
        ny = self.shape[1]
        s = len(centres)
        m = int(radius * inv) + 2  # rows each side (one of slack against rounding)
        c = centres - self.origin  # (S, 2) from the grid corner
        kx = np.floor(c[:, :1] * inv) + np.arange(-m, m + 1)  # (S, R) rows, as floats
        if m <= _SQUARE_ROWS:
            # Few rows: one y-range per centre (a square; fewer calls than per-row chords
            # for a few more candidates).
            ky = np.floor((c[:, 1:] + [-radius, radius]) * inv).T[:, :, None]  # (2, S, 1)
            ky += [[[-1.0]], [[1.0]]]  # a cell of slack against rounding
        else:
            # Horizontal gap from the centre to each row's x-interval; the disc's half chord
            # over that row bounds the row's y-range (1e-9 m slack against rounding). A row
            # the disc misses gets a zero chord: a few extra candidates, dropped by the caller.
            gap = np.abs(c[:, :1] - (kx + 0.5) * cell)
            gap -= 0.5 * cell
            np.maximum(gap, 0.0, out=gap)
            half = np.sqrt(np.maximum(radius * radius - gap * gap, 0.0))
            half += 1e-9
            ky = np.empty((2, *half.shape))  # first and last column of each row's slice
            np.subtract(c[:, 1:], half, out=ky[0])
            np.add(c[:, 1:], half, out=ky[1])
            ky *= inv
            np.floor(ky, out=ky)
        # Kept inside the grid so a slice never runs into the next row; rows outside the grid
        # give keys below 0 or past the last key: empty slices.
        ky = np.minimum(np.maximum(ky, 0.0), ny - 1)
        ky[1] += 1  # one past the last column
        bounds = np.searchsorted(self.keys, (ky + kx * ny).astype(np.int64))
        start = bounds[0].ravel()
        length = bounds[1].ravel() - start
        per_centre = length.reshape(s, -1).sum(axis=1)
        owner = np.repeat(np.arange(s), per_centre)
        # Flatten the slices: index = start of its slice + position within it.
        offset = np.cumsum(length)
        offset -= length
        index = np.repeat(start - offset, length)
        index += np.arange(len(index))
        return owner, index

    def cylinders(
        self, x: np.ndarray, y: np.ndarray, centres: np.ndarray, radius: float
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Points within ``radius`` horizontally (distance <= radius) of each centre.

        Args:
            x, y: ``(N,)`` coordinates of the indexed (sorted) cloud.
            centres: ``(S, 2)`` horizontal centres, metres.
            radius: cylinder radius, metres.

        Returns:
            ``(owner, index, dx, dy)``, all ``(P,)``: centre and point (int64) of every
            pair, contiguous per centre, centres in order, and the point's x, y offsets
            from its centre (the :meth:`candidates` within the disc).
        """
        m = int(radius / self.cell) + 2
        batch = max(1, _ROWS_PER_CALL // (2 * m + 1))
        if len(centres) > batch:  # bound the (centres, rows) temporaries for large radii
            firsts = range(0, len(centres), batch)
            parts = [self.cylinders(x, y, centres[i : i + batch], radius) for i in firsts]
            owner = np.concatenate([p[0] + i for p, i in zip(parts, firsts, strict=True)])
            rest = (np.concatenate([p[k] for p in parts]) for k in range(1, 4))
            return (owner, *rest)
        owner, index = self.candidates(centres, radius)
        per_centre = np.bincount(owner, minlength=len(centres))
        dx = x[index] - np.repeat(centres[:, 0], per_centre)
        dy = y[index] - np.repeat(centres[:, 1], per_centre)
        keep = np.flatnonzero(dx * dx + dy * dy <= radius * radius)
        return owner[keep], index[keep], dx[keep], dy[keep]


@dataclass(frozen=True)
class VoxelCloud:
    """A voxel-grid filtered cloud with its horizontal column index.

    Attributes:
        points: ``(V, 3)`` voxel centroids, metres, sorted by voxel (x column, then y,
            then z).
        counts: ``(V,)`` input points per voxel.
        index: :class:`ColumnIndex` of the centroids (columns = the voxels' columns).
    """

    points: np.ndarray
    counts: np.ndarray
    index: ColumnIndex

    @property
    def coords(self) -> np.ndarray:
        """``(3, V)`` x, y, z rows (a transposed view of :attr:`points`)."""
        return self.points.T

    def __len__(self) -> int:
        return len(self.points)


def voxel_grid(points: np.ndarray, voxel_size: float, lattice: bool = False) -> VoxelCloud:
    """Voxel-grid filter: replace the points of each occupied voxel by their centroid
    (voxels of edge ``voxel_size`` anchored at the cloud's lowest corner).

    Args:
        points: ``(N, 3)`` finite world points, metres.
        voxel_size: voxel edge, metres (> 0).
        lattice: anchor the voxels at multiples of ``voxel_size`` instead, so that any
            part of a cloud (a tile) has the same voxels as the whole.

    Raises:
        ValueError: ``voxel_size`` not positive, or a cloud so wide for its voxel size that
            the voxel keys overflow int64 (more than ~2^63 voxels in its bounding box).

    Returns:
        The :class:`VoxelCloud` of the ``V`` occupied voxels. One int64 key per point, the
        voxel's (column, z) index with the point's index packed in its low bits, sorted by
        ``np.sort`` (SIMD, much faster than ``argsort``), groups each voxel's points; the
        column is the key's most significant part, so the same order is the column index
        (no second sort, no separate spatial structure). The centroids are one
        sparse-matrix product.
    """
    if not voxel_size > 0:
        raise ValueError(f"voxel_size must be positive, got {voxel_size}")
    pts = np.asarray(points, dtype=np.float64)
    n = len(pts)
    if n == 0:
        index = ColumnIndex(np.empty(0, dtype=np.int64), (0.0, 0.0), float(voxel_size), (1, 1))
        return VoxelCloud(np.empty((0, 3)), np.empty(0, dtype=np.int64), index)
    # One transposed copy (ours, shifted and scaled in place below): every pass then runs over
    # contiguous rows (strided column views of an (N, 3) array are several times slower for
    # each reduction and cast).
    xyz = pts.T.copy()
    lo = xyz.min(axis=1)
    hi = xyz.max(axis=1).tolist()
    inv = 1.0 / voxel_size
    if lattice:  # absolute voxel indices floor(x / voxel), shifted to start at 0
        xyz *= inv
        np.floor(xyz, out=xyz)
        first = xyz.min(axis=1)
        xyz -= first[:, None]
        lo = first * voxel_size
        hi = (xyz.max(axis=1) * voxel_size + lo).tolist()
    # Voxels per axis from the extremes (the same monotone expression as the indices below),
    # checked before any cast so an absurd extent cannot overflow silently.
    nx, ny, nz = (int((h - m) * inv) + 1 for h, m in zip(hi, lo.tolist(), strict=True))
    if lattice:
        nx, ny, nz = (int(v) + 1 for v in xyz.max(axis=1))
    z_bits = (nz - 1).bit_length()
    n_bits = (n - 1).bit_length()
    key_bits = (nx * ny - 1).bit_length() + z_bits
    if key_bits > _KEY_BITS:
        raise ValueError(
            f"voxel grid of {nx} x {ny} x {nz} voxels is too large for int64 keys "
            f"(cloud extent / voxel_size {voxel_size} m)"
        )
    if not lattice:  # shifted to non-negative, truncation is floor: from the cloud's corner
        xyz -= lo[:, None]
        xyz *= inv
    packed = key_bits + n_bits <= _KEY_BITS
    if packed and nx * ny < 2**31 and z_bits + n_bits < 31:
        # The usual case, mostly in int32 (half the bytes per pass): the column kx * ny + ky,
        # and the low word (z index, point index), joined once in int64.
        kx, ky, kz = xyz.astype(np.int32)
        kx *= ny
        kx += ky  # column
        kz <<= n_bits
        kz |= np.arange(n, dtype=np.int32)
        key = kx.astype(np.int64)
        key <<= z_bits + n_bits
        key |= kz
    else:
        kx, ky, kz = xyz.astype(np.int64)
        key = kx
        key *= ny
        key += ky
        key <<= z_bits
        key |= kz  # the voxel key: (column, z), column = kx * ny + ky
        if packed:
            key <<= n_bits
            key |= np.arange(n, dtype=np.int64)
    if packed:  # the point index in the low bits: one SIMD sort, no argsort
        key.sort()
        order = key & ((1 << n_bits) - 1)
        key >>= n_bits
    else:  # too many voxels to pack the point index beside the key
        order = np.argsort(key)
        key = key[order]
    first = np.empty(n, dtype=bool)
    first[0] = True
    np.not_equal(key[1:], key[:-1], out=first[1:])
    indptr = np.flatnonzero(np.append(first, True))  # voxel starts, then n
    counts = np.diff(indptr)
    # Centroids as one sparse (V, N) averaging matrix (1 / count at each voxel's points) times
    # the (N, 3) cloud: a single compiled pass that gathers and sums (no sorted copies).
    weight = np.repeat(1.0 / counts, counts)
    average = sparse.csr_array((weight, order, indptr), shape=(len(counts), n))
    centroids = average @ pts
    columns = key[indptr[:-1]] >> z_bits
    index = ColumnIndex(columns, (lo[0], lo[1]), float(voxel_size), (nx, ny))
    return VoxelCloud(centroids, counts, index)


def voxel_downsample(
    points: np.ndarray, voxel_size: float
) -> tuple[np.ndarray, np.ndarray]:
    """Voxel-grid filter as arrays: ``(centroids (V, 3), counts (V,))`` of
    :func:`voxel_grid` (centroids sorted by voxel)."""
    grid = voxel_grid(points, voxel_size)
    return grid.points, grid.counts


@dataclass
class AccumulatorStatus:
    """What the accumulator holds: points, and metres travelled since the last release."""

    points: int
    travelled: float


class CloudAccumulator:
    """Accumulates world-frame clouds until the vehicle has travelled ``travel_distance``
    metres since the last release or ``max_points`` points are held (paper: 10 m, 10^6).

    Rows with NaN/inf are dropped and counted in :attr:`dropped_points`.
    """

    def __init__(self, travel_distance: float, max_points: int) -> None:
        self.travel_distance = float(travel_distance)
        self.max_points = int(max_points)
        self._chunks: list[np.ndarray] = []
        self._count = 0
        self._anchor: np.ndarray | None = None
        self._travelled = 0.0
        self.dropped_points = 0

    @property
    def status(self) -> AccumulatorStatus:
        return AccumulatorStatus(self._count, self._travelled)

    def add(self, points: np.ndarray, vehicle_position: np.ndarray | None) -> np.ndarray | None:
        """Add one scan; return the whole accumulated ``(N, 3)`` cloud when a threshold is
        reached (and start over), else None."""
        cloud, dropped = clean_points(points)
        self.dropped_points += dropped
        if len(cloud):
            self._chunks.append(cloud)
            self._count += len(cloud)
        if vehicle_position is not None:
            pos = np.asarray(vehicle_position, dtype=np.float64)[:3]
            if np.isfinite(pos).all():
                if self._anchor is None:
                    self._anchor = pos
                self._travelled = float(np.linalg.norm(pos - self._anchor))
        if self._count and (
            self._count >= self.max_points or self._travelled >= self.travel_distance
        ):
            return self.release()
        return None

    def release(self) -> np.ndarray:
        """Return everything held as one cloud and start over (anchor at the last pose)."""
        out = np.concatenate(self._chunks) if self._chunks else np.empty((0, 3))
        self._chunks = []
        self._count = 0
        self._anchor = None
        self._travelled = 0.0
        return out


def thin_by_distance(
    positions: np.ndarray, distance: float, radii: np.ndarray | None = None
) -> np.ndarray:
    """Greedy thinning: walk the points in the given order (best first) and keep each one
    that has no kept point within ``distance`` (nor, with ``radii``, a kept disc
    overlapping its own: centres closer than the sum of the radii); returns the (N,) bool
    mask of kept points.

    Computed in parallel rounds over the k-d tree's close pairs (a point is decided once no
    undecided better neighbour remains), which gives exactly the sequential greedy result.
    """
    pos = np.asarray(positions, dtype=np.float64)
    n = len(pos)
    keep = np.ones(n, dtype=bool)
    reach = distance if radii is None else max(distance, 2.0 * float(np.max(radii)))
    if n < 2 or reach <= 0:
        return keep
    pairs = cKDTree(pos).query_pairs(reach, output_type="ndarray")
    if radii is not None and len(pairs):
        gap = np.linalg.norm(pos[pairs[:, 0]] - pos[pairs[:, 1]], axis=1)
        pairs = pairs[(gap < radii[pairs[:, 0]] + radii[pairs[:, 1]]) | (gap < distance)]
    if len(pairs) == 0:
        return keep
    a = np.concatenate((pairs[:, 0], pairs[:, 1]))
    b = np.concatenate((pairs[:, 1], pairs[:, 0]))
    state = np.zeros(n, dtype=np.int8)  # 0 undecided, 1 kept, 2 dropped
    while True:
        open_pair = (state[a] == 0) & (state[b] == 0)
        best_nb = np.full(n, n, dtype=np.int64)
        np.minimum.at(best_nb, a[open_pair], b[open_pair])
        undecided = state == 0
        if not undecided.any():
            break
        winners = undecided & (np.arange(n) < best_nb)
        state[winners] = 1
        hit = winners[a] & (state[b] == 0)
        state[b[hit]] = 2
    return state == 1
