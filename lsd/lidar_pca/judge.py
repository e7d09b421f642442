"""Judging landing sites against a classified cloud's own labels and a local plane fit,
independently of the detector (its own least-squares plane on the raw points of each disc),
and a random-disc baseline to compare with (issue 16).

A site (centre, radius r) is safe when, with D the points within r horizontally and R those
within the clearance ring r < d <= r + clearance:

- D holds at least ``n_min`` points, and covers the disc: every node of a square lattice of
  spacing r/4 over the disc lies within r/2 of a point (a strip or a line of returns, as at
  a tile's or a flight strip's edge, says nothing of the ground beside it);
- the cloud's footprint covers the ring: every node of that lattice over the ring lies in
  it (no return is unknown ground, not clear ground: the edge of the data, water). The
  footprint is a raster of the cloud's typical point spacing s (from the median count of
  returns per occupied 2 m cell): the cells holding a return, closed by a disc of 3 cells
  (gaps of a sparse scan are sampling, not holes) and grown by one cell (what the returns
  at an edge speak for);
- the least-squares plane z = a x + b y + c of D has a slope of at most ``slope_max_deg``,
  an RMS distance of D from it of at most ``residual_max`` and no point of D farther than
  ``step_max`` from it;
- no point of R stands higher than ``obstacle_height`` above that plane;
- on a classified cloud (one holding ground, class 2), D and R hold ground points only,
  or, with ``roofs``, building (6) points only.
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from lsd.lidar_pca.settings import LidarPcaSettings

# Footprint raster: cells counted for the typical spacing (m), largest raster, and the disc
# of radius 3 cells that closes it.
_CELL = 2.0
_MAX_CELLS = 50_000_000
_DISC3 = np.hypot(*np.mgrid[-3:4, -3:4]) <= 3


@dataclass(frozen=True)
class JudgeRules:
    """The safety rule (module docstring); :meth:`from_settings` takes the detector's."""

    clearance: float = 1.0
    residual_max: float = 0.05
    step_max: float = 0.15
    slope_max_deg: float = 15.0
    obstacle_height: float = 0.5
    n_min: int = 10
    ground: tuple[int, ...] = (2,)
    roof: tuple[int, ...] = (6,)
    roofs: bool = False

    @classmethod
    def from_settings(cls, s: LidarPcaSettings) -> JudgeRules:
        return cls(
            clearance=s.obstacle_margin,
            residual_max=s.residual_max if s.residual_max is not None else math.inf,
            step_max=s.max_step if s.max_step is not None else math.inf,
            slope_max_deg=s.theta_max_deg,
            obstacle_height=s.obstacle_height if s.obstacle_height is not None else math.inf,
            n_min=s.n_min,
            ground=tuple(s.classes.ground),
            roof=tuple(s.classes.roof),
            roofs=s.classes.roofs,
        )


class Judge:
    """Judges discs on one cloud (the k-d tree is built once)."""

    def __init__(self, points: np.ndarray, codes: np.ndarray | None, rules: JudgeRules):
        self.points = np.asarray(points, dtype=np.float64)
        self.codes = codes if codes is not None and np.any(codes == 2) else None
        self.rules = rules
        self.tree = cKDTree(self.points[:, :2])
        self._footprint()

    def _footprint(self) -> None:
        """The raster of ground the returns speak for (module docstring)."""
        xy = self.points[:, :2]
        if len(xy) == 0:  # nothing seen (every disc is judged "no points" first)
            self.footprint = np.zeros((1, 1), dtype=bool)
            self.footprint_origin, self.footprint_cell = np.zeros(2), 1.0
            return
        lo = xy.min(axis=0) - 4 * _CELL  # room for the closing at the raster's border
        per_cell = np.unique(np.floor((xy - lo) / _CELL).astype(np.int64), axis=0,
                             return_counts=True)[1]
        cell = _CELL / math.sqrt(float(np.median(per_cell)))
        extent = xy.max(axis=0) - lo + 4 * _CELL
        cell = max(cell, math.sqrt(float(np.prod(extent)) / _MAX_CELLS))
        shape = tuple(np.ceil(extent / cell).astype(int) + 1)
        occupied = np.zeros(shape, dtype=bool)
        ij = np.floor((xy - lo) / cell).astype(np.int64)
        occupied[ij[:, 0], ij[:, 1]] = True
        closed = ndimage.binary_closing(occupied, structure=_DISC3)
        self.footprint = ndimage.binary_dilation(closed, structure=np.ones((3, 3), bool))
        self.footprint_origin, self.footprint_cell = lo, cell

    def judge(self, centres: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, list[str]]:
        """(K,) bool safe, and per disc "" or the first rule it breaks."""
        centres = np.asarray(centres, dtype=np.float64).reshape(-1, 2)
        radii = np.broadcast_to(np.asarray(radii, dtype=np.float64), (len(centres),))
        reasons = [self._one(c, r) for c, r in zip(centres, radii, strict=True)]
        return np.array([not r for r in reasons], dtype=bool), reasons

    def _one(self, centre: np.ndarray, radius: float) -> str:
        ru = self.rules
        near = np.asarray(self.tree.query_ball_point(centre, radius + ru.clearance), dtype=int)
        if near.size == 0:
            return "no points"
        p = self.points[near]
        d = np.hypot(p[:, 0] - centre[0], p[:, 1] - centre[1])
        disc = d <= radius
        if disc.sum() < ru.n_min:
            return "too few points"
        if not self._covered(centre, radius):
            return "disc not covered"
        if not self._ring_in_footprint(centre, radius):
            return "ring not covered"
        if self.codes is not None:
            c = self.codes[near]
            if not (np.isin(c, ru.ground).all() or (ru.roofs and np.isin(c, ru.roof).all())):
                bad = c[~np.isin(c, ru.ground)]
                return f"class {int(np.bincount(bad).argmax())} in disc or ring"
        q = p[disc]
        a = np.column_stack((q[:, 0] - centre[0], q[:, 1] - centre[1], np.ones(len(q))))
        coef, *_ = np.linalg.lstsq(a, q[:, 2], rcond=None)
        tilt = math.hypot(coef[0], coef[1])
        if math.degrees(math.atan(tilt)) > ru.slope_max_deg:
            return "slope"
        plane = (p[:, 0] - centre[0]) * coef[0] + (p[:, 1] - centre[1]) * coef[1] + coef[2]
        height = (p[:, 2] - plane) / math.sqrt(1.0 + tilt * tilt)  # perpendicular
        if np.sqrt(np.mean(height[disc] ** 2)) > ru.residual_max:
            return "residual"
        if np.abs(height[disc]).max() > ru.step_max:
            return "step"
        if (height[~disc] > ru.obstacle_height).any():
            return "obstacle in ring"
        return ""

    def _covered(self, centre: np.ndarray, radius: float) -> bool:
        step = np.arange(-4, 5) * (radius / 4)
        nodes = np.stack(np.meshgrid(step, step), axis=-1).reshape(-1, 2)
        nodes = nodes[np.hypot(nodes[:, 0], nodes[:, 1]) <= radius * (1 + 1e-9)] + centre
        gap, _ = self.tree.query(nodes, distance_upper_bound=radius / 2)
        return bool(np.isfinite(gap).all())


    def _ring_in_footprint(self, centre: np.ndarray, radius: float) -> bool:
        outer = radius + self.rules.clearance
        step = np.arange(-math.ceil(outer / (radius / 4)), math.ceil(outer / (radius / 4)) + 1)
        nodes = np.stack(np.meshgrid(step, step), axis=-1).reshape(-1, 2) * (radius / 4)
        d = np.hypot(nodes[:, 0], nodes[:, 1])
        nodes = nodes[(d > radius) & (d <= outer * (1 + 1e-9))] + centre
        ij = np.floor((nodes - self.footprint_origin) / self.footprint_cell).astype(np.int64)
        shape = np.array(self.footprint.shape)
        inside = ((ij >= 0) & (ij < shape)).all(axis=1)
        return bool(inside.all() and self.footprint[ij[:, 0], ij[:, 1]].all())


def random_discs(points: np.ndarray, n: int, radius: float,
                 rng: np.random.Generator) -> np.ndarray:
    """(n, 2) centres of random discs on the cloud: at random points of it (so a disc
    lies where there is data, with the cloud's own density of cover types)."""
    pick = rng.choice(len(points), size=min(n, len(points)), replace=False)
    return np.asarray(points)[pick, :2]


def score(safe: np.ndarray, reasons: list[str]) -> str:
    """"82.0% safe (41 of 50; class 5 in disc or ring 6, residual 3)"."""
    if len(safe) == 0:
        return "no sites"
    why = Counter(r for r in reasons if r)
    detail = ", ".join(f"{k} {v}" for k, v in why.most_common())
    return (f"{100.0 * safe.mean():.1f}% safe ({int(safe.sum())} of {len(safe)}"
            + (f"; {detail}" if detail else "") + ")")


__all__ = ["Judge", "JudgeRules", "random_discs", "score"]
