"""Downward pinhole depth camera rendered from the terrain, with the thesis' depth error
model (eq. 3.2) and the structure-from-motion / stereo source switch."""

from __future__ import annotations

import sys
from collections import Counter, deque
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit
from scipy.special import ndtri

from sitl.sensors.rangefinder import RangeFinder
from sitl.sensors.raycast import HeightBounds, PinholeRays, coarse_terrain
from sitl.sensors.region import GroundRegion
from sitl.sensors.settings import DepthCameraSettings
from sitl.terrain import Terrain
from sitl.terrain.moving_hits import see_moving

STEREO = "stereo"
SFM = "sfm"

# Coarsest level of detail rendered: 2 x 2 cells. Coarser levels (0.8 m cells for the Mars
# mission's f = 128 px camera at cruise) smooth rocks out of the cruise-altitude map, and
# the flights then spend their verifications on sites the low pass rejects.
_MAX_LEVEL = 1

# Standard normal deviates by inverse transform of 16-bit uniforms: the quantiles of the
# 65536 equiprobable bins (tails cut at 4.3 sigma). Raw random bytes and one table lookup
# cost a quarter of Generator.standard_normal per pixel.
_NORMAL_QUANTILES = ndtri((np.arange(65536) + 0.5) / 65536).astype(np.float32)


@dataclass(frozen=True)
class RenderedDepth:
    """One depth image as the simulator renders it (converted to ``lsd.frames.DepthFrame``
    by the composition root).

    Attributes:
        depth: (height, width) float32, metres along the optical axis; NaN = no depth.
        sigma: (height, width) float32, 1-sigma depth error (m) of each pixel (eq. 3.2);
            NaN where there is no depth.
        fx, fy, cx, cy: pinhole intrinsics (px); pixel (u, v) = (column, row).
        width, height: image size (px).
        position: (3,) camera centre, ENU metres.
        rotation: (3, 3) rotation camera frame (x right, y down, z optical axis) -> ENU.
        timestamp: clock seconds of the pose.
        source: ``"sfm"`` or ``"stereo"``.
        baseline: the baseline b (m) the error model used.
    """

    depth: np.ndarray
    sigma: np.ndarray
    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    position: np.ndarray
    rotation: np.ndarray
    timestamp: float
    source: str
    baseline: float = 0.0
    rendered: np.ndarray | None = None
    """(height, width) bool: the pixels rendered when only a region of the ground was
    asked for (the others are NaN and say nothing about the ground); None: all."""
    moving: Any = None
    """Moving obstacles in view: (:class:`sitl.terrain.moving.ObstacleSnapshot` at
    ``timestamp``, (height, width) int16 index of the obstacle each pixel sees, -1 where
    none); None when the world has none in view."""


def nadir_rotation(yaw: float) -> np.ndarray:
    """Rotation camera -> ENU of a camera looking straight down from a vehicle with heading
    ``yaw`` (rad, ENU, counter-clockwise from east): image right = vehicle right, image up
    = vehicle forward, optical axis = down. Returns (3, 3)."""
    c, s = np.cos(yaw), np.sin(yaw)
    forward = np.array([c, s, 0.0])
    right = np.array([s, -c, 0.0])
    return np.column_stack((right, -forward, np.array([0.0, 0.0, -1.0])))


def depth_sigma(depth: np.ndarray, focal_px: float, baseline: float, disparity_sigma: float):
    """Thesis eq. 3.2: sigma_z = z^2 / (f b) * sigma_d (same shape as ``depth``)."""
    return np.square(depth) * (disparity_sigma / (focal_px * baseline))


@njit(cache=True, nogil=True)
def _deviates(bins, quantiles, out):
    """Each pixel's standard normal deviate ``quantiles[bins[pixel]]`` into ``out``."""
    width = out.shape[1]
    for i in range(out.shape[0]):
        for j in range(width):
            out[i, j] = quantiles[bins[i * width + j]]


@njit(cache=True, nogil=True)
def _sigma_and_noise(depth, factor, deviates, sigma):
    """Eq. 3.2 per pixel into ``sigma`` (``depth**2 * factor``, as :func:`depth_sigma`),
    and, with ``deviates``, the noise ``deviate * sigma`` added to ``depth`` in place (a
    depth that falls to zero or below is NaN)."""
    for i in range(depth.shape[0]):
        for j in range(depth.shape[1]):
            d = depth[i, j]
            s = d * d * factor
            sigma[i, j] = s
            if deviates is not None:
                d = d + deviates[i, j] * s
                depth[i, j] = d if not d <= 0 else np.nan


def _noise_bins(rng: np.random.Generator, n: int) -> np.ndarray:
    """``n`` uniform 16-bit numbers, the bytes of ``rng.bytes(2 * n)`` (uint16, (n,))."""
    bits = rng.bit_generator
    if (n % 4 == 0 and sys.byteorder == "little" and isinstance(bits, np.random.PCG64)
            and not bits.state["has_uint32"]):
        # Generator.bytes takes 32-bit halves of the 64-bit outputs, low half first: with
        # no half left over from an earlier draw, the same bytes as the raw outputs, at
        # half the cost (no copies through a bytes object).
        return bits.random_raw(n // 4).view(np.uint16)
    return np.frombuffer(rng.bytes(2 * n), dtype=np.uint16)


class DepthSourceSelector:
    """Chooses the depth source from the range finder's AGL, with hysteresis: stereo
    below ``stereo_below``, SfM above ``sfm_above``, unchanged in between. No AGL (beyond
    the range finder's range) counts as high. The first reading picks stereo unless it is
    above ``sfm_above``."""

    def __init__(self, stereo_below: float, sfm_above: float) -> None:
        self.stereo_below = stereo_below
        self.sfm_above = sfm_above
        self.source: str | None = None

    def update(self, agl: float | None) -> bool:
        """Feed one AGL reading (m or None); returns True when the source changed."""
        high = agl is None or agl > self.sfm_above
        if self.source is None:
            new = SFM if high else STEREO
        elif self.source == STEREO and high:
            new = SFM
        elif self.source == SFM and agl is not None and agl < self.stereo_below:
            new = STEREO
        else:
            new = self.source
        changed = new != self.source
        self.source = new
        return changed


class DepthCamera:
    """Nadir depth camera over a terrain.

    Call :meth:`render` with the vehicle pose at the perception rate (and optionally
    :meth:`observe_pose` more often, so the SfM baseline sees the motion in between). It
    returns a :class:`RenderedDepth` or None when there is no depth (bad pose, camera under
    ground, SfM without enough lateral motion); the reasons are counted in
    :attr:`skipped` and reported as events, never raised.

    With ``settings.level_of_detail`` (the default) a frame is rendered from the terrain's
    mean-height level whose cell is nearest the pixel footprint (AGL / focal_px, log2
    rounded, at most 2 x 2 cells): full resolution below 1.41 cells per pixel (72 m AGL
    for a 256 px focal length over 0.2 m cells), 0.4 m cells above, nearer what a depth
    pixel averages than one point of the full terrain per pixel. There the depth is within
    a fifth of its noise sigma of the full-resolution one on 99% of the pixels
    (tests/sitl/test_sensors.py).

    Args:
        terrain: the world.
        settings: camera and error model.
        rangefinder: the AGL source for the stereo/SfM switch (default: a
            :class:`RangeFinder` sharing ``rng``).
        rng: noise source; default: seeded with 0.
    """

    def __init__(
        self,
        terrain: Terrain,
        settings: DepthCameraSettings | None = None,
        rangefinder: RangeFinder | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.terrain = terrain
        self.settings = s = settings or DepthCameraSettings()
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.rangefinder = rangefinder or RangeFinder(terrain, rng=self.rng)
        self.selector = DepthSourceSelector(s.stereo_below, s.sfm_above)
        self.skipped: Counter[str] = Counter()
        self._events: list[dict[str, Any]] = []
        self._history: deque[tuple[float, float, float]] = deque()
        self._last_skip: str | None = None
        self._bounds: dict[int, HeightBounds] = {}  # per level of detail
        self.fx = self.fy = float(s.focal_px)
        self.cx = (s.width - 1) / 2.0
        self.cy = (s.height - 1) / 2.0
        v, u = np.mgrid[0 : s.height, 0 : s.width]
        # Ray directions in the camera frame with unit z: the ray parameter is the depth.
        self._xc = ((u - self.cx) / self.fx).astype(np.float32)
        self._yc = ((v - self.cy) / self.fy).astype(np.float32)
        # A nadir camera's rays all have ENU z = -1 (the optical axis points down).
        self._dz = np.full(u.shape, -1.0, dtype=np.float32)
        self._rays: tuple[float, PinholeRays] | None = None  # (yaw, its rays)

    @property
    def source(self) -> str | None:
        """Current depth source ("stereo", "sfm"), None before the first frame."""
        return self.selector.source

    def drain_events(self) -> list[dict[str, Any]]:
        """Events since the last call: ``{"event": "depth_source", "source", "agl"}`` on
        each switch, ``{"event": "depth_skipped", "reason", ...}`` when frames start being
        skipped for a reason."""
        events, self._events = self._events, []
        return events

    def observe_pose(self, position, yaw: float, timestamp: float) -> None:
        """Record a pose for the SfM baseline (non-finite poses are ignored)."""
        p = np.asarray(position, dtype=np.float64).reshape(-1)
        if p.size != 3 or not (np.all(np.isfinite(p)) and np.isfinite(timestamp)):
            return
        if self._history and timestamp < self._history[-1][0]:
            self._history.clear()  # time went backwards (a new run): start over
        self._history.append((float(timestamp), float(p[0]), float(p[1])))
        while self._history and self._history[0][0] < timestamp - self.settings.sfm_window:
            self._history.popleft()

    def sfm_baseline(self) -> float:
        """Lateral distance (m) between the newest pose and the oldest within the window,
        capped at ``sfm_max_baseline``."""
        if len(self._history) < 2:
            return 0.0
        _, x0, y0 = self._history[0]
        _, x1, y1 = self._history[-1]
        return min(float(np.hypot(x1 - x0, y1 - y0)), self.settings.sfm_max_baseline)

    def render(
        self,
        position,
        yaw: float,
        timestamp: float,
        agl: float | None = None,
        region: GroundRegion | None = None,
    ) -> RenderedDepth | None:
        """Render the depth image seen from ``position`` (3,) ENU m with heading ``yaw``.

        Args:
            position: camera centre, ENU metres.
            yaw: heading, rad ENU.
            timestamp: clock seconds.
            agl: the range finder's reading if the caller has one (e.g. from the
                autopilot's DISTANCE_SENSOR); default: measured by :attr:`rangefinder`.
            region: render only the pixels whose measured points (noise included) can
                land in this ground box, and those they depend on
                (:class:`~sitl.sensors.region.GroundRegion`); the others are NaN and
                :attr:`RenderedDepth.rendered` tells which. Ignored in a world with
                moving obstacles (they stand above the ground the march bounds).

        Returns:
            the frame, or None (see :attr:`skipped` and :meth:`drain_events`).
        """
        s = self.settings
        p = np.asarray(position, dtype=np.float64).reshape(-1)
        if p.size != 3 or not (
            np.all(np.isfinite(p)) and np.isfinite(yaw) and np.isfinite(timestamp)
        ):
            return self._skip("invalid_pose")
        self.observe_pose(p, yaw, timestamp)
        if agl is None or not np.isfinite(agl):
            agl = self.rangefinder.measure(p, yaw, time=timestamp)
        if self.selector.update(agl):
            self._events.append(
                {
                    "event": "depth_source",
                    "source": self.selector.source,
                    "agl": None if agl is None else round(float(agl), 2),
                }
            )
        true_agl = self.rangefinder.true_agl(p)
        if true_agl <= 0:
            return self._skip("camera_below_ground")
        if self.selector.source == SFM:
            baseline = self.sfm_baseline()
            if baseline < s.sfm_min_baseline:
                return self._skip("sfm_baseline", baseline=round(baseline, 2))
            max_range = s.max_depth
        else:
            baseline = s.stereo_baseline
            max_range = min(s.stereo_max_range, s.max_depth)
        rotation = nadir_rotation(yaw)
        bounds, level = self._height_bounds(true_agl)
        # Refined to 0.5 mm at full resolution, coarser with the level of detail.
        rays = self._pinhole_rays(yaw, rotation)
        tolerance = 5e-4 * 2**level
        rendered = deviates = None
        if s.noise:  # each pixel's standard normal deviate (drawn first: see below)
            deviates = np.empty((s.height, s.width), np.float32)
            _deviates(_noise_bins(self.rng, s.width * s.height), _NORMAL_QUANTILES, deviates)
        if region is None or self.terrain.moving is not None:
            depth = rays.cast(bounds, p, t_max=max_range, step=s.march_step, tolerance=tolerance)
        else:
            # Knowing the deviates bounds every measured depth about the true one t:
            # t + deviate * sigma(t), sigma(t) = t^2 sigma_d / (f b).
            error = (np.float32(0.0), np.float32(0.0))
            if deviates is not None:
                error = (np.float32(s.disparity_sigma_px / (s.focal_px * baseline)), deviates)
            depth, rendered = rays.cast_within(
                bounds, p, region, error, t_max=max_range, step=s.march_step,
                tolerance=tolerance,
            )
        if self.terrain.known is not None:  # an elevation model: no return off it or on nodata
            hit_x, hit_y = p[0] + depth * rays.dx, p[1] + depth * rays.dy
            depth[~self.terrain.has_ground(hit_x, hit_y)] = np.nan
        moving = None
        if self.terrain.moving is not None:  # the nearer of the terrain and what moves
            moving = see_moving(self.terrain.moving.at(timestamp), p, rotation, self, depth,
                                max_range)
        # depth_sigma's factor, in its precision; then sigma and the noise in one pass.
        factor = np.float32(s.disparity_sigma_px) / (np.float32(s.focal_px) * np.float32(baseline))
        sigma = np.empty_like(depth)
        _sigma_and_noise(depth, factor, deviates, sigma)
        self._last_skip = None
        return RenderedDepth(
            depth=depth,
            sigma=sigma,
            fx=self.fx,
            fy=self.fy,
            cx=self.cx,
            cy=self.cy,
            width=s.width,
            height=s.height,
            position=p.copy(),
            rotation=rotation,
            timestamp=float(timestamp),
            source=self.selector.source or "",
            baseline=float(baseline),
            rendered=rendered,
            moving=moving,
        )

    def _height_bounds(self, agl: float) -> tuple[HeightBounds, int]:
        """Bounds of the terrain at the level of detail of the pixel footprint ``agl / f``
        (built on first use), and that level."""
        level = 0
        if self.settings.level_of_detail:
            footprint = agl / self.settings.focal_px / self.terrain.cell_size
            level = int(np.clip(np.rint(np.log2(max(footprint, 1e-9))), 0, _MAX_LEVEL))
        bounds = self._bounds.get(level)
        if bounds is None:
            bounds = self._bounds[level] = HeightBounds(coarse_terrain(self.terrain, level))
        return bounds, level

    def _pinhole_rays(self, yaw: float, rotation: np.ndarray) -> PinholeRays:
        """The pixels' rays in ENU for heading ``yaw`` (kept while the heading holds)."""
        if self._rays is None or self._rays[0] != yaw:
            r = rotation.astype(np.float32)
            dx, dy = (r[k, 0] * self._xc + r[k, 1] * self._yc + r[k, 2] for k in range(2))
            self._rays = (yaw, PinholeRays.from_components(dx, dy, self._dz))
        return self._rays[1]

    def _skip(self, reason: str, **details: Any) -> None:
        self.skipped[reason] += 1
        # One event when skipping starts (or its reason changes), not one per frame.
        if reason != self._last_skip:
            self._events.append({"event": "depth_skipped", "reason": reason, **details})
        self._last_skip = reason
        return None
