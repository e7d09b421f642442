"""Is the ground of a site seen? (beyond the paper; setting ``max_gap``)

No return is not clear ground: it is the edge of the data, water (no return), a gap under
canopy or dropped points. A site's disc and clearance ring must therefore be covered by
returns (of any class), judged on a square lattice of r_min / 4 around the site centre plus
64 nodes on its outer circle:

- every node within ``extent = radius + obstacle_margin + band`` of the centre lies within
  ``gap = max_gap * spacing`` of a return;
- ``spacing`` is the mean point spacing of the site's own disc, sqrt(pi r^2 / n) with n its
  returns (at least n_min: a sparser disc is dropped anyway), so the rule scales with the
  cloud: gaps of a sparse but complete scan (lines 1.3 m apart at 2 points/m^2) and of
  random pulses (a node 2.5 spacings from every return has probability exp(-pi 2.5^2),
  3e-9) are sampling, not holes;
- ``band = gap - spacing``: the lattice reaches that far beyond the ring, so at the edge of
  the data the ring may overhang the last returns by one spacing (the ground a return
  speaks for), not by a whole ``gap`` (at 2 points/m^2 a 1.5 m gap would otherwise let the
  1 m ring lie wholly off the data).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from lsd.lidar_pca.settings import LidarPcaSettings

# Nodes on each site's outer circle: a straight edge of the data is met within
# R (1 - cos(pi / 64)), 6 mm at R = 5 m, of where the circle touches it.
_CIRCLE_NODES = 64
# Lattice nodes queried at once (bounds the temporaries).
_NODES_PER_BATCH = 2_000_000


def coverage_scale(radius: np.ndarray, n_disc: np.ndarray,
                   settings: LidarPcaSettings) -> tuple[np.ndarray, np.ndarray]:
    """(gap, band) per site (module docstring), metres, from its radius and disc count."""
    assert settings.max_gap is not None
    spacing = np.sqrt(np.pi * radius * radius / np.maximum(n_disc, settings.n_min))
    gap = settings.max_gap * spacing
    return gap, gap - spacing


def max_reach(settings: LidarPcaSettings) -> float:
    """The farthest (m) from a site centre the coverage check looks for returns: extent +
    gap at the sparsest disc kept (n_min returns within r_max)."""
    if settings.max_gap is None:
        return 0.0
    spacing = math.sqrt(math.pi / settings.n_min) * settings.r_max
    return settings.obstacle_margin + (2 * settings.max_gap - 1) * spacing


def unseen_distance(tree: cKDTree, centres: np.ndarray, extent: np.ndarray, gap: np.ndarray,
                    step: float) -> np.ndarray:
    """(K,) horizontal distance from each centre to its nearest node (within ``extent``)
    farther than ``gap`` from every return of ``tree`` (2-D); inf where all are seen.

    Nodes: a square lattice of ``step`` anchored at the centre, plus the circle of radius
    ``extent``; all sites at once (lattice offsets are shared, sorted by distance, so a
    site's nodes are a prefix of them).
    """
    k = len(centres)
    out = np.full(k, np.inf)
    if k == 0:
        return out
    n = int(math.ceil(float(extent.max()) / step))
    ticks = np.arange(-n, n + 1) * step
    lattice = np.stack(np.meshgrid(ticks, ticks), axis=-1).reshape(-1, 2)
    dist = np.hypot(lattice[:, 0], lattice[:, 1])
    order = np.argsort(dist, kind="stable")
    lattice, dist = lattice[order], dist[order]
    angle = np.linspace(0.0, 2.0 * np.pi, _CIRCLE_NODES, endpoint=False)
    circle = np.column_stack((np.cos(angle), np.sin(angle)))
    per_site = np.searchsorted(dist, extent + 1e-9, side="right") + _CIRCLE_NODES
    first = 0
    while first < k:  # batches of sites, at most _NODES_PER_BATCH nodes each (one at least)
        last = first + max(1, int(np.searchsorted(np.cumsum(per_site[first:]),
                                                  _NODES_PER_BATCH, side="right")))
        sites = np.arange(first, min(last, k))
        counts = per_site[sites] - _CIRCLE_NODES
        owner = np.repeat(sites, counts)
        local = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
        ring_owner = np.repeat(sites, _CIRCLE_NODES)
        offset = np.concatenate((lattice[local],
                                 np.tile(circle, (len(sites), 1)) * extent[ring_owner, None]))
        owner = np.concatenate((owner, ring_owner))
        node_dist = np.concatenate((dist[local], extent[ring_owner]))
        nearest, _ = tree.query(centres[owner] + offset,
                                distance_upper_bound=float(gap[sites].max()))
        unseen = nearest > gap[owner]
        np.minimum.at(out, owner[unseen], node_dist[unseen])
        first = int(sites[-1]) + 1
    return out


__all__ = ["coverage_scale", "max_reach", "unseen_distance"]
