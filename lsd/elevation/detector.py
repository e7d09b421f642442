"""The elevation-map landing-site detector (thesis section 3; DESIGN.md section 7).

Each depth frame is checked, its valid pixels are back-projected and fused into a
robot-centric :class:`~lsd.elevation.map.ElevationMap`; the map is then analysed: a plane fit
over the vehicle footprint around every cell gives slope, roughness and uncertainty, a
threshold test gives the safe mask, one Euclidean distance transform gives every cell's
size, non-maximum suppression picks sites, and a maximum filter gives each site's obstacle
altitude. Sites come out as :class:`lsm.SiteObservation` records, already threshold-filtered.

``observation_altitude`` is the camera's current height above the site, or, if larger, the
greatest height from which any cell within ``footprint_radius + look_margin`` of the site was
best seen: a site redetected at 2.5 m whose surroundings were only seen from 20 m (or
obliquely from the edge of the view) is not reported as seen from 2.5 m, which keeps
verification meaningful. A site that passes the step test near
it only thanks to the noise tolerance is reported as seen from no lower than
``doubtful_altitude``; in the fine (low-altitude) map, near means any cell within
``footprint_radius + look_margin`` that sticks out by more than ``max_step``, and sites are
placed as far from such cells as their blocks allow.

Normalisation of the emitted values (so they can enter the loss unaltered):
``roughness = roughness_m / max_roughness`` and ``uncertainty = sigma_m / max_uncertainty``,
where ``sigma_m`` is the RMS 1-sigma fused height error over the footprint window. Because a
site beyond either limit is not emitted, both lie in [0, 1].

Bad input never raises: bad pixels are dropped and counted, a frame that cannot be used
(empty, NaN pose, inconsistent shapes) is skipped, counted and reported as an event.

Longer than 500 lines: the analysis of the coarse and fine maps (roughness, uncertainty,
footprints, site selection) shares its windows and masks; the map itself is map.py.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections import Counter
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from lsd.elevation.map import ElevationMap, cell_looks, pooled_level
from lsd.elevation.projection import back_project, block_points, median32, valid_points
from lsd.elevation.settings import DetectorSettings, ElevationMapSettings
from lsd.frames import DepthFrame
from lsd.plane_fit import PlaneFit, fit_planes
from lsd.site_selection import (
    cells_at_least,
    largest_at,
    maximum_box,
    obstacle_altitude,
    rank_sites,
    safe_mask,
    site_size,
    size_cap,
    step_levels,
    step_room_at,
)
from lsm.records import SiteObservation


@dataclass(frozen=True)
class MapAnalysis:
    """The last detection's intermediate grids (for plots and debugging).

    Attributes:
        fit: the per-cell :class:`~lsd.plane_fit.PlaneFit`.
        safe: (n, n) bool safe mask.
        size: (n, n) site size, metres.
        origin_index: world cell index of cell [0, 0].
        resolution: cell side, metres.
    """

    fit: PlaneFit
    safe: np.ndarray
    size: np.ndarray
    origin_index: tuple[int, int]
    resolution: float


class ElevationDetector:
    """Fuses depth frames into an elevation map and reports landing sites.

    Use :meth:`process` once per frame; :meth:`counters` and :meth:`drain_events` tell what
    was dropped or skipped and why.
    """

    def __init__(
        self,
        map_settings: ElevationMapSettings | None = None,
        settings: DetectorSettings | None = None,
    ) -> None:
        map_settings = map_settings or ElevationMapSettings()
        self.map = ElevationMap(map_settings)
        self.fine_map = ElevationMap(map_settings.fine())
        self.settings = settings or DetectorSettings()
        self.agl: float | None = None  # camera height above the ground of the last frame
        # The last detection's grids over its analysed window; embedded in whole-grid
        # arrays only when :attr:`last_analysis` is asked for.
        self._analysis: tuple | None = None
        self._last_analysis: MapAnalysis | None = None
        self._counters: Counter[str] = Counter()
        self._events: list[dict[str, Any]] = []
        self._last_skip: str | None = None

    @property
    def map_settings(self) -> ElevationMapSettings:
        return self.map.settings

    @property
    def last_analysis(self) -> MapAnalysis | None:
        """The last detection's intermediate grids, or None (nothing observed yet)."""
        if self._last_analysis is None and self._analysis is not None:
            fit, safe, size, shape, window, origin, r = self._analysis
            self._last_analysis = MapAnalysis(*_embedded(fit, safe, size, shape, window), origin, r)
        return self._last_analysis

    @property
    def low(self) -> bool:
        """Whether the last frame came from below ``fine_below`` (the fine map is in use)."""
        return self.agl is not None and self.agl < self.map_settings.fine_below

    def counters(self) -> dict[str, int]:
        """Counts of frames, pixels, points and observations by fate (a copy)."""
        return dict(self._counters)

    def drain_events(self) -> list[dict[str, Any]]:
        """Events since the last call, each a JSON-able dict with ``"event"``:
        ``{"event": "frame_skipped", "reason", "frame_time"}`` when frames start being
        skipped (or the reason changes); every skipped frame is counted in :meth:`counters`.
        """
        events, self._events = self._events, []
        return events

    def process(self, frame: DepthFrame) -> list[SiteObservation]:
        """Fuse ``frame`` into the map and return the sites it now shows.

        Returns an empty list when the frame is skipped.
        """
        if not self.integrate(frame):
            return []
        return self.detect(
            np.asarray(frame.position, dtype=np.float64), float(frame.timestamp), frame.source
        )

    def ground_needed(self, x: float, y: float) -> tuple[float, float, float, float, int, int]:
        """What a frame taken above world (x, y) must show for :meth:`integrate` to fuse
        the same points as from the whole view: ``(x_min, x_max, y_min, y_max, reach,
        block)``, the ground box (ENU m) the maps will cover once recentred there, the
        pixels (each way) of the box filter that places points, and the largest pixel
        block fused as one point. The box joins the coarse map's window now and centred
        on (x, y) (a low camera recentres it only past a slack); the fine map's lies in
        the latter."""
        grid = self.map
        r = grid.resolution
        n0, n1 = grid.shape
        i0 = math.floor(x / r) - n0 // 2
        j0 = math.floor(y / r) - n1 // 2
        if grid._centred:
            ci, cj = (int(v) for v in grid.origin_index)
            i0, i1 = min(i0, ci), max(i0, ci) + n0
            j0, j1 = min(j0, cj), max(j0, cj) + n1
        else:
            i1, j1 = i0 + n0, j0 + n1
        reach = self.map_settings.placement_smoothing // 2
        return i0 * r, i1 * r, j0 * r, j1 * r, reach, _LARGEST_BLOCK

    def integrate(self, frame: DepthFrame) -> bool:
        """Fuse ``frame`` into the map (recentred on the camera); False if it was skipped.

        Where a map's cells are much larger than the ground a pixel sees (a low camera),
        square blocks of pixels are combined first (inverse-variance weighted, as the map
        would combine them anyway), so the map fuses a few points per block instead of
        every pixel: see :func:`_pixel_block`.
        """
        self._counters["frames_received"] += 1
        reason = self._frame_problem(frame)
        if reason is not None:
            return self._skip(frame, reason)
        f32 = np.float32
        depth = np.asarray(frame.depth, dtype=f32)
        self._counters["pixels_received"] += depth.size
        rendered = None if frame.rendered is None else np.asarray(frame.rendered, dtype=bool)
        if rendered is not None and rendered.shape != depth.shape:
            return self._skip(frame, "shape_mismatch")
        if rendered is not None:
            self._counters["pixels_not_rendered"] += depth.size - int(np.count_nonzero(rendered))
            part = _rendered_part(frame, rendered)
            if part is None:
                return self._skip(frame, "no_valid_depth")
            frame, rendered = part, part.rendered
            depth = np.asarray(frame.depth, dtype=f32)
        valid = self._valid_pixels(frame, depth, rendered)
        n_valid = int(np.count_nonzero(valid))
        if n_valid == 0:
            return self._skip(frame, "no_valid_depth")
        placement = _placement_depth(depth, valid, self.map_settings.placement_smoothing)
        # Points are placed horizontally along the smoothed depth but keep their own
        # height: placing each point with its own noisy depth would crowd the
        # short-depth (high) points towards the nadir and bias cells upwards by about
        # 2 sigma^2 / depth.
        position = np.asarray(frame.position, dtype=np.float64)
        rotation = np.asarray(frame.rotation, dtype=np.float64)
        k = frame.intrinsics
        height, width = depth.shape
        # Back-projection of every pixel in single precision, offsets from the camera
        # (world offset = depth * R @ ray); bad pixels are dropped afterwards.
        xn = ((np.arange(width) - k.cx) / k.fx).astype(f32)
        yn = ((np.arange(height) - k.cy) / k.fy).astype(f32)
        # drop: the vertical offset of the point below (or above) the camera.
        east, north, drop, variance = back_project(
            depth, placement, _NO_SIGMA if frame.sigma is None else np.asarray(frame.sigma, f32),
            rotation, xn, yn, f32(self.map_settings.min_sigma**2),
        )

        now = float(frame.timestamp)
        self._last_skip = None
        everything = n_valid == depth.size
        # The valid pixels' points, one per pixel (views of the grids if all are valid).
        grids = (east, north, drop, variance)
        if everything:
            points = tuple(a.reshape(-1) for a in grids)
        else:
            points = valid_points(valid, *grids, n_valid)
        # Height above the ground from a subsample of the points (a median is robust).
        step = max(1, n_valid // 4096)
        self.agl = -float(median32(np.ascontiguousarray(points[2][:: step])))
        ground_per_pixel = max(self.agl, 0.0) / max(k.fx, k.fy)
        # In place, east, north and drop become world x, y and z (single precision keeps
        # better than a millimetre within kilometres of home, ample for cells of 1 cm+);
        # the grids (for the pixel blocks) and the valid pixels' copies of them alike.
        # (When every pixel is valid the points are views of the grids: translated once.)
        for x, y, z in [grids[:3]] if everything else [grids[:3], points[:3]]:
            x += f32(position[0])
            y += f32(position[1])
            z += f32(position[2])
        maps = (self.map, self.fine_map) if self.low else (self.map,)
        blocks: dict[int, tuple] = {}
        for index, grid in enumerate(maps):
            # A coarse map that is not analysed need only hold the (small, low) view: it
            # follows the camera in steps of a quarter of its side.
            slack = 0.25 * grid.settings.size if self.low and index == 0 else 0.0
            grid.recentre(position[0], position[1], slack)
            self._counters["cells_forgotten"] += grid.forget_older_than(now)
            # The coarse map is not analysed while the fine one is: blocks as large as its
            # cells will do.
            share = 1.0 if self.low and index == 0 else 0.25
            block = _pixel_block(grid.resolution, ground_per_pixel, depth.shape, share)
            pool = 1 if self.low else self._analysis_pool(grid)
            if pool > 1:
                # Analysed in pooled cells: 2 x 2 pixel blocks no larger than an analysed
                # cell blur it no more than the analysis does (a quarter of the points).
                pooled = grid.resolution * pool
                block = max(block, min(2, _pixel_block(pooled, ground_per_pixel, depth.shape, 1.0)))
            if block > 1:
                if block not in blocks:  # both maps may take the same blocks
                    blocks[block] = block_points(east, north, drop, variance, valid, block)
                x, y, z, var, count = blocks[block]
            else:
                x, y, z, var = points
                count = None
            fused = grid.fuse_columns(
                x, y, z, var, now, camera_height=float(position[2]), count=count
            )
            if index == 0:
                self._counters["points_fused"] += fused
                self._counters["points_outside_map"] += n_valid - fused
        self._counters["frames_fused"] += 1
        return True

    def detect(
        self, camera_position: np.ndarray, now: float, source: str = ""
    ) -> list[SiteObservation]:
        """Analyse the map and return its landing sites, best first.

        The fine map is analysed while the last frame came from below ``fine_below``,
        the coarse map otherwise.

        Args:
            camera_position: (3,) ENU metres, for the observation altitude.
            now: clock seconds stamped on the observations; cells older than ``max_age``
                are forgotten first.
            source: depth source appended to the observations' source (``"elevation:sfm"``).
        """
        s = self.settings
        m = self.fine_map if self.low else self.map
        self._counters["cells_forgotten"] += m.forget_older_than(now)
        # The fine map is never pooled: the sites it gives are the ones verification
        # re-detects from low altitude, in its own cells.
        pool = self._analysis_pool(m) if m is self.map else 1
        r = m.resolution * pool  # side of an analysed cell
        # Only the cells within a footprint window of an observed cell can get a fit, and
        # so be safe: analyse the bounding box of the observed cells grown by that window
        # plus one ring (never safe), which gives the same sites as the whole grid.
        half = max(1, int(round(s.footprint_radius / r)))
        reach = int(np.ceil(s.footprint_radius / r - 1e-9))
        box = _observed_box(m, (max(half, reach) + 1) * pool)
        self._last_analysis = None
        if box is None:
            self._analysis = None
            return []
        origin = (int(m.origin_index[0]), int(m.origin_index[1]))
        if pool > 1:
            # Blocks aligned to world cell indices, so that sites keep their positions.
            box = _aligned(box, origin, pool, m.shape)
            if box is None:
                self._analysis = None
                return []
        window = (slice(box[0], box[1]), slice(box[2], box[3]))
        if pool > 1:
            mean, variance, top, cell_variance, looks = pooled_level(
                m.mean[window], m.variance[window], m.top[window], m.closest[window], pool
            )
            looks = looks.astype(np.float32)
        else:
            mean, variance, top, cell_variance = (
                m.mean[window], m.variance[window], m.top[window], None
            )
            looks = cell_looks(m.closest[window])
        fit = fit_planes(
            mean,
            variance,
            r,
            s.footprint_radius,
            top=top,
            tolerance=s.noise_tolerance,
            cell_variance=cell_variance,
        )
        level = step_levels(fit, s, r)  # step_hazards: 2 hazard, 1 doubtful
        safe = safe_mask(fit, s, level >= 2)
        size = site_size(safe, r)
        # World index (in analysed cells) of the analysed window's cell [0, 0].
        box_origin = ((origin[0] + box[0]) // pool, (origin[1] + box[2]) // pool)
        if pool > 1:  # the analysis is its own grid
            n0, n1 = mean.shape
            self._analysis = (fit, safe, size, (n0, n1), (slice(0, n0), slice(0, n1)),
                              box_origin, r)
        else:
            self._analysis = (fit, safe, size, m.shape, window, origin, r)
        # A site is only as trustworthy as the farthest look at the ground under its
        # footprint (the smallest camera height each cell was seen from, largest over the
        # footprint).
        # Only cells large enough to be sites are ranked, so only they need a quality.
        # (The grids are C-ordered: the ranked cells' values are gathered by flat index.)
        ranked, ranked_i, ranked_j = cells_at_least(size, s.footprint_radius)
        if len(ranked) == 0:
            return []
        f32 = np.float32
        farthest_look = maximum_box(looks, 2 * reach + 1)
        with np.errstate(invalid="ignore"):
            # Between equally roomy cells prefer the best-seen one (so that a low hover
            # redetects the site right below it), then the smoothest and most certain.
            # (Elementwise, so the same values as over the whole grid: numpy's exp rounds
            # each element alike wherever it lies in an array.)
            quality = np.take(fit.roughness, ranked) * f32(-0.15 / s.max_roughness)
            quality -= np.take(fit.sigma, ranked) * f32(0.15 / s.max_uncertainty)
            quality += f32(0.3)
            quality += np.exp(np.take(farthest_look, ranked) * f32(-0.1)) * f32(0.7)
        cv2.patchNaNs(quality, 0.0)
        # Low down, where sites are verified, a site also keeps as far as its block allows
        # from every step beyond max_step, forgiven by the noise tolerance or not: small
        # rocks read low in rendered, fused depth, so a forgiven step may be a rock.
        # Its room is only read where it is less than both the (capped) size and the doubt
        # ring's radius.
        ranked_size = np.take(size, ranked)
        room = None
        if m is self.fine_map:
            bound = np.maximum(np.minimum(ranked_size, size_cap(s, r)),
                               s.footprint_radius + s.look_margin)
            room = step_room_at(fit, s, r, ranked_i, ranked_j, bound)
        i, j = rank_sites(ranked_i, ranked_j, ranked_size, quality, box_origin, r, s, room=room)
        if len(i) == 0:
            return []
        # The obstacle altitude from the map's own cells (the highest, not a block's mean),
        # around the map cell at the centre of each analysed cell.
        top = obstacle_altitude(
            m.top[window],
            m.variance[window],
            m.resolution,
            s.obstacle_radius,
            sites=(i * pool + pool // 2, j * pool + pool // 2),
        )
        n0, n1 = size.shape
        xs = (box_origin[0] + np.arange(n0) + 0.5) * r
        ys = (box_origin[1] + np.arange(n1) + 0.5) * r
        z = fit.height[i, j]
        roughness = np.clip(fit.roughness[i, j] / s.max_roughness, 0.0, 1.0)
        uncertainty = np.clip(fit.sigma[i, j] / s.max_uncertainty, 0.0, 1.0)
        # The observation altitude asks more than the quality: every cell of the footprint
        # and of the ring around it where a rock would matter must have been seen that close.
        looked_at = _largest_within(looks, i, j, (s.footprint_radius + s.look_margin) / r)
        altitude = np.maximum(float(camera_position[2]) - z, looked_at)
        # A site that is safe only because noise forgives a step near it is no proof of a
        # close look: it may not verify, nor overwrite a conclusive look. Low down, near
        # means anywhere in the footprint or the ring of look_margin around it.
        doubt = level[i, j] >= 1
        if room is not None:  # the sites' own rooms (the cells come in row-major order)
            at = np.searchsorted(ranked, i * size.shape[1] + j)
            doubt |= room[at] < s.footprint_radius + s.look_margin
        altitude = np.where(doubt, np.maximum(altitude, s.doubtful_altitude), altitude)
        label = f"{s.source}:{source}" if source else s.source
        # Python floats by .tolist() (the same values as float() of each numpy scalar).
        columns = zip(
            xs[i].tolist(), ys[j].tolist(), z.tolist(), roughness.tolist(),
            uncertainty.tolist(), size[i, j].tolist(), top.tolist(), altitude.tolist(),
            strict=True,
        )
        observations = [
            SiteObservation(
                x=x,
                y=y,
                z=zz,
                roughness=rr,
                uncertainty=uu,
                size=ss,
                obstacle_altitude=max(oo, zz),
                observation_altitude=hh,
                timestamp=now,
                source=label,
            )
            for x, y, zz, rr, uu, ss, oo, hh in columns
        ]
        self._counters["observations_emitted"] += len(observations)
        return observations

    def _analysis_pool(self, grid: ElevationMap) -> int:
        """How many cells of ``grid`` (per side) one analysed cell pools at the last frame's
        height: the largest power of two up to ``max_analysis_pool`` whose cell side is at
        most ``analysis_cell_ratio`` times that height and at most the footprint radius."""
        s = self.settings
        if self.agl is None:
            return 1
        largest = min(s.analysis_cell_ratio * self.agl, s.footprint_radius)
        pool = 1
        while 2 * pool <= s.max_analysis_pool and 2 * pool * grid.resolution <= largest:
            pool *= 2
        return pool

    # -- input checks -------------------------------------------------------------------

    def _skip(self, frame: DepthFrame, reason: str) -> bool:
        self._counters[f"frames_skipped_{reason}"] += 1
        # One event when skipping starts or its reason changes, not one per frame.
        if reason == self._last_skip:
            return False
        self._last_skip = reason
        timestamp = getattr(frame, "timestamp", None)
        self._events.append(
            {
                "event": "frame_skipped",
                "reason": reason,
                "frame_time": float(timestamp)
                if isinstance(timestamp, (int, float)) and math.isfinite(timestamp)
                else None,
            }
        )
        return False

    @classmethod
    def _frame_problem(cls, frame: DepthFrame) -> str | None:
        """Why the frame cannot be used at all, or None."""
        try:
            return cls._check_frame(frame)
        except (TypeError, ValueError, AttributeError):  # fields of the wrong kind
            return "malformed_frame"

    @staticmethod
    def _check_frame(frame: DepthFrame) -> str | None:
        depth = np.asarray(frame.depth)
        if depth.ndim != 2 or depth.size == 0:
            return "empty_frame"
        if not np.issubdtype(depth.dtype, np.number):
            return "bad_depth_type"
        k = frame.intrinsics
        intrinsics = np.array([k.fx, k.fy, k.cx, k.cy], dtype=np.float64)
        if not np.isfinite(intrinsics).all() or k.fx <= 0 or k.fy <= 0:
            return "bad_intrinsics"
        if depth.shape != (k.height, k.width):
            return "shape_mismatch"
        if frame.sigma is not None and np.shape(frame.sigma) != depth.shape:
            return "shape_mismatch"
        position = np.asarray(frame.position, dtype=np.float64)
        rotation = np.asarray(frame.rotation, dtype=np.float64)
        if position.shape != (3,) or rotation.shape != (3, 3):
            return "bad_pose"
        if not (np.isfinite(position).all() and np.isfinite(rotation).all()):
            return "bad_pose"
        # np.allclose(rotation.T @ rotation, eye, atol=1e-3) written out (allclose's own
        # checks cost more than the test).
        if not (np.abs(rotation.T @ rotation - _EYE) <= _ORTHONORMAL).all():
            return "bad_pose"
        if not math.isfinite(float(frame.timestamp)):
            return "bad_timestamp"
        return None

    def _valid_pixels(
        self, frame: DepthFrame, depth: np.ndarray, rendered: np.ndarray | None = None
    ) -> np.ndarray:
        """(H, W) bool usable pixels; counts every dropped pixel by reason (among the
        ``rendered`` ones, when only those were measured)."""
        s = self.map_settings
        with np.errstate(invalid="ignore"):
            # NaN fails every comparison; min_range >= 0 leaves only 0 to the last test.
            valid = depth >= s.min_range
            valid &= depth <= s.max_range
            if s.min_range <= 0:
                valid &= depth > 0
        if rendered is not None:
            valid &= rendered
        c = self._counters
        if not (valid.all() if rendered is None else np.array_equal(valid, rendered)):
            # The reasons are only worth counting when something failed.
            finite = np.isfinite(depth)
            with np.errstate(invalid="ignore"):
                positive = depth > 0
            if rendered is not None:  # what was not measured is not dropped
                c["pixels_dropped_nonfinite"] += int(np.count_nonzero(rendered & ~finite))
                finite &= rendered
            else:
                c["pixels_dropped_nonfinite"] += int(np.count_nonzero(~finite))
            c["pixels_dropped_nonpositive"] += int(np.count_nonzero(finite & ~positive))
            c["pixels_dropped_out_of_range"] += int(
                np.count_nonzero(finite & positive & ~valid)
            )
        if frame.sigma is not None:
            sigma = np.asarray(frame.sigma, dtype=np.float32)
            with np.errstate(invalid="ignore"):
                good_sigma = sigma >= 0
                good_sigma &= sigma < np.inf
            if not good_sigma.all():
                bad = valid & ~good_sigma
                if rendered is None or bad.any():  # unrendered pixels have no sigma
                    c["pixels_dropped_bad_sigma"] += int(np.count_nonzero(bad))
                valid &= good_sigma
        return valid


# Largest side (px) of the pixel blocks fused as one point (see _pixel_block).
_LARGEST_BLOCK = 8
_NO_SIGMA = np.zeros((0, 0), np.float32)  # frames without a per-pixel depth error
_EYE = np.eye(3)
_ORTHONORMAL = 1e-3 + 1e-5 * _EYE  # np.allclose's bounds (atol=1e-3, rtol=1e-5) about eye


def _rendered_part(frame: DepthFrame, rendered: np.ndarray) -> DepthFrame | None:
    """``frame`` cut to the rows and columns holding its rendered pixels, from and to
    multiples of the largest pixel block (so blocks stay where they were), or None when
    nothing was rendered. Pixels keep their rays: the principal point moves with the cut."""
    rows = np.flatnonzero(rendered.any(axis=1))
    if len(rows) == 0:
        return None
    cols = np.flatnonzero(rendered.any(axis=0))
    b = _LARGEST_BLOCK
    height, width = rendered.shape
    r0, c0 = int(rows[0]) // b * b, int(cols[0]) // b * b
    r1 = min(-(-(int(rows[-1]) + 1) // b) * b, height)
    c1 = min(-(-(int(cols[-1]) + 1) // b) * b, width)
    if (r0, c0, r1, c1) == (0, 0, height, width):
        return frame
    cut = (slice(r0, r1), slice(c0, c1))
    k = frame.intrinsics
    return dataclasses.replace(
        frame,
        depth=np.asarray(frame.depth)[cut],
        sigma=None if frame.sigma is None else np.asarray(frame.sigma)[cut],
        intrinsics=dataclasses.replace(k, cx=k.cx - c0, cy=k.cy - r0, width=c1 - c0,
                                       height=r1 - r0),
        rendered=rendered[cut],
    )


def _placement_depth(depth: np.ndarray, valid: np.ndarray, kernel: int) -> np.ndarray:
    """(H, W) float32 depth averaged over the valid pixels of a ``kernel`` x ``kernel`` box
    (``depth`` itself where ``kernel`` is 1), used only to place points horizontally."""
    if kernel <= 1:
        return depth
    if valid.all():  # the plain box mean (the border reflects valid pixels too)
        return cv2.blur(depth, (kernel, kernel))
    total = cv2.blur(np.where(valid, depth, np.float32(0.0)), (kernel, kernel))
    share = cv2.blur(valid.astype(np.float32), (kernel, kernel))
    with np.errstate(divide="ignore", invalid="ignore"):
        total /= share
    return np.where(valid & (share > 0), total, depth)


def _pixel_block(
    resolution: float, ground_per_pixel: float, shape: tuple[int, int], share: float = 0.25
) -> int:
    """Side (pixels, a power of two, at most 8) of the pixel blocks to combine before
    fusing into cells of ``resolution``: the largest block that still sees at most
    ``share`` of a cell's side, so blocks straddling a cell edge blur it by little.
    1: no blocks."""
    if ground_per_pixel <= 0:
        return 1
    block = 1
    while block < _LARGEST_BLOCK and 2 * block * ground_per_pixel <= share * resolution:
        block *= 2
    while block > 1 and min(shape) < 2 * block:
        block //= 2
    return block


def _largest_within(grid: np.ndarray, i: np.ndarray, j: np.ndarray, radius: float) -> np.ndarray:
    """(k,) largest value of ``grid`` over the cells within ``radius`` cells of cell
    (i[k], j[k]) (a disk; the nearest edge cell stands for cells beyond the grid)."""
    di, dj = _disk(radius)
    return largest_at(grid, np.asarray(i, np.int64), np.asarray(j, np.int64), di, dj)


@functools.lru_cache(maxsize=8)
def _disk(radius: float) -> tuple[np.ndarray, np.ndarray]:
    """Row and column offsets (int64, read-only) of the cells within ``radius`` cells of a
    cell (the same few radii every frame)."""
    n = int(np.floor(radius + 1e-9))
    di, dj = np.mgrid[-n : n + 1, -n : n + 1]
    inside = np.hypot(di, dj) <= radius + 1e-9
    offsets = di[inside].astype(np.int64), dj[inside].astype(np.int64)
    for a in offsets:
        a.flags.writeable = False
    return offsets


def _aligned(
    box: tuple[int, int, int, int], origin: tuple[int, int], pool: int, shape: tuple[int, int]
) -> tuple[int, int, int, int] | None:
    """``box`` (i0, i1, j0, j1) moved out to whole blocks of ``pool`` cells whose world
    indices are multiples of ``pool`` (blocks cut by the grid's edge are left out), or None
    when no whole block is left."""
    out = []
    sides = ((box[0], box[1], origin[0], shape[0]), (box[2], box[3], origin[1], shape[1]))
    for lo, hi, o, n in sides:
        lo -= (o + lo) % pool
        if lo < 0:
            lo += pool
        hi = lo + -(-(hi - lo) // pool) * pool
        while hi > n:
            hi -= pool
        if hi <= lo:
            return None
        out += [lo, hi]
    return out[0], out[1], out[2], out[3]


def _observed_box(grid: ElevationMap, margin: int) -> tuple[int, int, int, int] | None:
    """(i0, i1, j0, j1): the bounding box of ``grid``'s observed cells grown by ``margin``
    cells on each side and clipped to the grid, or None when no cell is observed."""
    bounds = grid.observed_bounds()
    if bounds is None:
        return None
    i0, i1, j0, j1 = bounds
    n0, n1 = grid.shape
    return max(i0 - margin, 0), min(i1 + margin, n0), max(j0 - margin, 0), min(j1 + margin, n1)


def _embedded(
    fit: PlaneFit,
    safe: np.ndarray,
    size: np.ndarray,
    shape: tuple[int, int],
    window: tuple[slice, slice],
) -> tuple[PlaneFit, np.ndarray, np.ndarray]:
    """The analysis of ``window`` placed in whole-grid arrays (no fit, unsafe elsewhere)."""
    if all(w.start == 0 and w.stop == n for w, n in zip(window, shape, strict=True)):
        return fit, safe, size

    def embed(array: np.ndarray, fill: float) -> np.ndarray:
        out = np.full(shape, fill, dtype=array.dtype)
        out[window] = array
        return out

    fields = {
        f.name: embed(getattr(fit, f.name), 0.0 if f.name == "observed_fraction" else np.nan)
        for f in dataclasses.fields(fit)
    }
    return PlaneFit(**fields), embed(safe, False), embed(size, 0.0)
