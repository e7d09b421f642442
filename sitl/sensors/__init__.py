"""Simulated sensors over the terrain: a nadir depth camera (SfM / stereo error model)
and a downward laser range finder. They take the vehicle pose (ENU position, yaw) as plain
arguments, so the same code serves whatever flies the vehicle."""

from sitl.sensors.camera import (
    DepthCamera,
    DepthSourceSelector,
    RenderedDepth,
    depth_sigma,
    nadir_rotation,
)
from sitl.sensors.rangefinder import RangeFinder
from sitl.sensors.raycast import cast_rays
from sitl.sensors.settings import DepthCameraSettings, RangeFinderSettings

__all__ = [
    "DepthCamera",
    "DepthCameraSettings",
    "DepthSourceSelector",
    "RangeFinder",
    "RangeFinderSettings",
    "RenderedDepth",
    "cast_rays",
    "depth_sigma",
    "nadir_rotation",
]
