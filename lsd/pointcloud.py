"""Point-cloud plumbing for the LiDAR detector: cleaning, voxel-grid downsampling and the
accumulator that decides when an accumulated cloud is processed (Loureiro et al. 2021,
sections 4.1-4.2).

All clouds are ``(N, 3)`` float64 arrays of world points, ENU metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree


def clean_points(points: np.ndarray) -> tuple[np.ndarray, int]:
    """Keep the finite rows of a cloud.

    Args:
        points: ``(N, 3)`` array-like (any extra columns are dropped).

    Returns:
        ``(cloud, dropped)``: the ``(M, 3)`` float64 rows whose three coordinates are finite,
        and the number of rows dropped. A cloud of the wrong shape is dropped whole.
    """
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] < 3:
        return np.empty((0, 3)), int(arr.shape[0]) if arr.ndim >= 1 else 1
    arr = arr[:, :3]
    finite = np.isfinite(arr).all(axis=1)
    return np.ascontiguousarray(arr[finite]), int(arr.shape[0] - finite.sum())


def voxel_downsample(
    points: np.ndarray, voxel_size: float, return_inverse: bool = False
) -> tuple[np.ndarray, np.ndarray] | tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Voxel-grid filter: replace the points of each occupied voxel by their centroid
    (voxels of edge ``voxel_size`` anchored at the cloud's lowest corner).

    Args:
        points: ``(N, 3)`` finite world points, metres.
        voxel_size: voxel edge, metres (> 0).
        return_inverse: also return, for every input point, the index of its voxel.

    Returns:
        ``(centroids, counts)``: ``(V, 3)`` centroids and ``(V,)`` points per voxel, in the
        order of the sorted voxel keys (deterministic); with ``return_inverse`` a third
        ``(N,)`` array maps input points to voxels. Computed with one argsort of int64 voxel
        keys and ``np.bincount`` over the sorted points.
    """
    if voxel_size <= 0:
        raise ValueError(f"voxel_size must be positive, got {voxel_size}")
    pts = np.asarray(points, dtype=np.float64)
    if len(pts) == 0:
        empty = (np.empty((0, 3)), np.empty(0, dtype=np.int64))
        return (*empty, np.empty(0, dtype=np.int64)) if return_inverse else empty
    # Work on contiguous coordinate rows: column reductions of an (N, 3) array are slow.
    coords = np.ascontiguousarray(pts.T)
    # Shifted to non-negative, truncation is floor: voxel indices from the cloud's corner.
    keys = ((coords - coords.min(axis=1, keepdims=True)) * (1.0 / voxel_size)).astype(np.int64)
    # One int64 key per voxel (the raveled 3D index); sorting it groups each voxel's points.
    dims = keys.max(axis=1) + 1
    flat = (keys[0] * dims[1] + keys[1]) * dims[2] + keys[2]
    order = np.argsort(flat)
    sorted_keys = flat[order]
    first = np.empty(len(flat), dtype=bool)
    first[0] = True
    np.not_equal(sorted_keys[1:], sorted_keys[:-1], out=first[1:])
    group = np.cumsum(first) - 1  # voxel of each sorted point
    n_vox = int(group[-1]) + 1
    counts = np.bincount(group, minlength=n_vox)
    centroids = np.stack(
        [np.bincount(group, coords[k][order], minlength=n_vox) for k in range(3)], axis=1
    )
    centroids /= counts[:, None]
    if return_inverse:
        inverse = np.empty(len(flat), dtype=np.int64)
        inverse[order] = group
        return centroids, counts, inverse
    return centroids, counts


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


def thin_by_distance(positions: np.ndarray, distance: float) -> np.ndarray:
    """Greedy thinning: walk the points in the given order (best first) and keep each one
    that has no kept point within ``distance``; returns the (N,) bool mask of kept points.

    Computed in parallel rounds over the k-d tree's close pairs (a point is decided once no
    undecided better neighbour remains), which gives exactly the sequential greedy result.
    """
    pos = np.asarray(positions, dtype=np.float64)
    n = len(pos)
    keep = np.ones(n, dtype=bool)
    if n < 2 or distance <= 0:
        return keep
    pairs = cKDTree(pos).query_pairs(distance, output_type="ndarray")
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
