"""Simulated LiDAR over the terrain height grid: all rays of a scan cast at once
(:func:`sitl.sensors.raycast.cast_rays`), seeded range noise, world-frame points out.

Two beam patterns:

- ``spinning``: a multi-channel spinning LiDAR (VLP-16 like: 16 channels over +-15 deg,
  ``azimuth_steps`` firings per turn) whose spin axis is tilted from vertical by
  ``mount_tilt_deg`` about the body y axis, so that a sensor on a UAV sweeps the ground;
- ``downward``: a solid-state/flash LiDAR looking straight down with a square field of view of
  ``channels`` x ``azimuth_steps`` beams.

Points are ENU metres; rays without a hit within ``max_range`` (sky, beyond range), closer
than ``min_range``, or ending where an elevation model has no ground (off its grid, nodata)
give no point.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from sitl.sensors.raycast import BlockMax, cast_rays
from sitl.terrain import Terrain
from sitl.terrain.moving_hits import nearer, ray_hits

MAX_RAYS = 2_000_000
"""Rays of one scan: each is marched over the terrain every scan (a VLP-16 fires 28,800 a
turn, a 128-channel LiDAR about 260,000)."""


class LidarSettings(BaseModel):
    """Beam pattern, range limits and noise of the simulated LiDAR."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    pattern: Literal["spinning", "downward"] = Field("spinning", description="beam pattern")
    channels: int = Field(16, ge=1, le=512, description="lasers (spinning) or rows (downward)")
    vertical_fov_deg: float = Field(
        30.0, gt=0, lt=180, description="spread of the channels (spinning) / square FOV (deg)"
    )
    azimuth_steps: int = Field(
        900, ge=1, le=20_000, description="firings per turn (spinning) / columns (downward); "
        "with channels at most 2,000,000 rays a scan (a VLP-16 fires 28,800)"
    )
    mount_tilt_deg: float = Field(
        90.0, ge=0, le=180, description="spin axis tilt from body up (deg); 90: axis horizontal"
    )
    min_range: float = Field(0.5, ge=0, le=10_000, description="closest return (m)")
    max_range: float = Field(
        100.0, gt=0, le=10_000, description="farthest return (m), up to 10 km (airborne "
        "LiDARs reach a few km)"
    )
    range_noise_std: float = Field(
        0.03, ge=0, le=100, description="1-sigma range noise (m), up to 100"
    )
    march_step: float | None = Field(
        None, ge=0.01, le=100, description="horizontal ray-march step (m), 0.01 .. 100; "
        "None: the terrain cell size"
    )

    @model_validator(mode="after")
    def _ranges(self):
        if self.max_range <= self.min_range:
            raise ValueError(f"max_range: {self.max_range} m must exceed min_range")
        if self.channels * self.azimuth_steps > MAX_RAYS:
            raise ValueError(
                f"azimuth_steps: {self.channels} channels x {self.azimuth_steps} steps is "
                f"{self.channels * self.azimuth_steps:,} rays a scan, more than {MAX_RAYS:,}"
            )
        return self


def beam_directions(settings: LidarSettings) -> np.ndarray:
    """(channels * azimuth_steps, 3) unit beam directions in the body frame (x forward/east
    at yaw 0, y left, z up)."""
    s = settings
    half = math.radians(s.vertical_fov_deg) / 2.0
    if s.pattern == "downward":
        a = np.linspace(-half, half, s.channels)
        b = np.linspace(-half, half, s.azimuth_steps)
        ta, tb = np.meshgrid(np.tan(a), np.tan(b), indexing="ij")
        d = np.stack((ta.ravel(), tb.ravel(), -np.ones(ta.size)), axis=1)
        return d / np.linalg.norm(d, axis=1, keepdims=True)
    elev = np.linspace(-half, half, s.channels) if s.channels > 1 else np.zeros(1)
    azim = np.linspace(0.0, 2.0 * math.pi, s.azimuth_steps, endpoint=False)
    e, a = np.meshgrid(elev, azim, indexing="ij")
    d = np.stack((np.cos(e) * np.cos(a), np.cos(e) * np.sin(a), np.sin(e)), axis=-1)
    t = math.radians(s.mount_tilt_deg)
    tilt = np.array([[math.cos(t), 0, math.sin(t)], [0, 1, 0], [-math.sin(t), 0, math.cos(t)]])
    return d.reshape(-1, 3) @ tilt.T


class LidarScanner:
    """A LiDAR on the vehicle: :meth:`scan` returns the world points of one full scan.

    Args:
        terrain: the world.
        settings: beam pattern, ranges and noise.
        rng: range-noise source (default: seeded with 0).
    """

    def __init__(
        self,
        terrain: Terrain,
        settings: LidarSettings | None = None,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.terrain = terrain
        self.settings = settings or LidarSettings()
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self._beams = beam_directions(self.settings)
        self._block_max = BlockMax(terrain)
        self.skipped = 0  # scans refused for a bad pose

    def scan(self, position, yaw: float, time: float | None = None) -> np.ndarray:
        """World points (N, 3) ENU metres hit by one scan from ``position`` (3,) with heading
        ``yaw`` (rad); an empty (0, 3) array for a non-finite pose. With the simulated
        ``time`` (s) the world's moving obstacles are where they are then."""
        p = np.asarray(position, dtype=np.float64).reshape(-1)
        if p.size != 3 or not (np.isfinite(p).all() and math.isfinite(yaw)):
            self.skipped += 1
            return np.empty((0, 3))
        c, s = math.cos(yaw), math.sin(yaw)
        rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        dirs = self._beams @ rz.T
        r = cast_rays(
            self.terrain,
            p,
            dirs,
            t_max=self.settings.max_range,
            step=self.settings.march_step,
            block_max=self._block_max,
        )
        if time is not None and self.terrain.moving is not None:  # the nearer hit
            nearer(r, *ray_hits(self.terrain.moving.at(time), p, *dirs.T,
                                t_max=self.settings.max_range))
        hit = np.isfinite(r) & (r >= self.settings.min_range)
        if self.terrain.known is not None:  # an elevation model: no return off it or on nodata
            ends = p + dirs * np.where(hit, r, 0.0)[:, None]
            hit &= self.terrain.has_ground(ends[:, 0], ends[:, 1])
        r = r[hit]
        if self.settings.range_noise_std > 0:
            r = r + self.settings.range_noise_std * self.rng.standard_normal(len(r))
        return p + dirs[hit] * r[:, None]


__all__ = ["LidarScanner", "LidarSettings", "beam_directions"]
