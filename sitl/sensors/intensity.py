"""Greyscale frames of the nadir camera, rendered from the same ray casting as depth.

A :class:`~sitl.sensors.camera.RenderedDepth` gives each pixel's depth along the optical
axis and the camera's pose; the pixel's ray then hits the terrain at
``position + depth * R (x_c, y_c, 1)`` with ``x_c = (u - cx) / fx``, ``y_c = (v - cy) / fy``.
The frame is the world's shaded albedo there (:class:`sitl.terrain.albedo.AlbedoMap`, its
grain band-limited to the pixel footprint ``depth / fx``), times an exposure gain, plus
Gaussian read noise, quantised to 8 bits. Pixels without a return (NaN depth: beyond the
far clip, off an elevation model) are black. Pixels that see a moving obstacle show its own
shaded surface and grain (:func:`sitl.terrain.moving_hits.obstacle_radiance`), which
travel with it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from sitl.sensors.camera import RenderedDepth
from sitl.terrain.moving_hits import obstacle_radiance

if TYPE_CHECKING:  # OpenCV is loaded only by whoever builds an albedo map
    from sitl.terrain.albedo import AlbedoMap


class IntensityCameraSettings(BaseModel):
    """Exposure and noise of the greyscale camera, and the sun that lights the world."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    gain: float = Field(
        400.0, gt=0, le=100_000, description="digital numbers per unit of shaded albedo "
        "(exposure): 400 puts sunlit regolith (0.25) near 100 of 255; up to 100,000"
    )
    noise_std: float = Field(
        2.0, ge=0, le=64, description="1-sigma read noise, digital numbers of 255, up to 64"
    )
    sun_azimuth: float = Field(
        135.0, ge=0, le=360, description="sun azimuth, deg clockwise from north, 0 .. 360"
    )
    sun_elevation: float = Field(
        50.0, ge=1, le=90, description="sun elevation above the horizon, deg, 1 .. 90"
    )
    ambient: float = Field(
        0.35, ge=0, le=1, description="share of the light from the sky, reaching every "
        "surface whatever its slope, 0 .. 1"
    )


def hit_points(rendered: RenderedDepth) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ENU x, y, z (each (height, width) float64) where each pixel's ray meets the terrain;
    NaN where there is no depth."""
    r = rendered
    v, u = np.mgrid[0 : r.height, 0 : r.width]
    xc = (u - r.cx) / r.fx
    yc = (v - r.cy) / r.fy
    depth = r.depth.astype(np.float64)
    rot = np.asarray(r.rotation, dtype=np.float64)
    p = np.asarray(r.position, dtype=np.float64)
    return tuple(p[k] + depth * (rot[k, 0] * xc + rot[k, 1] * yc + rot[k, 2]) for k in range(3))


def render_intensity(
    rendered: RenderedDepth,
    albedo: AlbedoMap,
    rng: np.random.Generator,
    settings: IntensityCameraSettings | None = None,
) -> np.ndarray:
    """The (height, width) uint8 frame seen with ``rendered``'s pose (see the module's
    docstring); read noise from ``rng`` (one draw per pixel when ``noise_std`` > 0)."""
    s = settings or IntensityCameraSettings()
    x, y, z = hit_points(rendered)
    seen = np.isfinite(rendered.depth)
    frame = np.zeros(rendered.depth.shape, dtype=np.float32)
    if seen.any():
        footprint = rendered.depth[seen].astype(np.float64) / rendered.fx
        frame[seen] = s.gain * albedo.radiance(x[seen], y[seen], z[seen], footprint)
    if rendered.moving is not None:  # what moves carries its own texture along
        snapshot, index = rendered.moving
        on = seen & (index >= 0)
        footprint = rendered.depth[on].astype(np.float64) / rendered.fx
        frame[on] = s.gain * obstacle_radiance(snapshot, index[on], x[on], y[on], z[on],
                                               footprint, albedo)
    if s.noise_std > 0:
        frame += rng.standard_normal(frame.shape, dtype=np.float32) * np.float32(s.noise_std)
    frame = np.clip(np.rint(frame), 0, 255).astype(np.uint8)
    frame[~seen] = 0
    return frame
