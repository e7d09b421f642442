"""Conversion of the simulator's rendered depth images into the detectors' frames."""

from __future__ import annotations

from lsd.frames import DepthFrame, Intrinsics
from sitl.sensors import RenderedDepth


def to_depth_frame(rendered: RenderedDepth) -> DepthFrame:
    """The :class:`lsd.frames.DepthFrame` carrying ``rendered``'s image, per-pixel sigma,
    intrinsics, pose, time and source (arrays are shared, not copied)."""
    r = rendered
    return DepthFrame(
        depth=r.depth,
        sigma=r.sigma,
        intrinsics=Intrinsics(fx=r.fx, fy=r.fy, cx=r.cx, cy=r.cy, width=r.width, height=r.height),
        position=r.position,
        rotation=r.rotation,
        timestamp=r.timestamp,
        source=r.source,
    )
