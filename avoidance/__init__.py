"""Obstacle detection in the descent from optical flow (Lee et al. 2019, sections 3.3 and 4.2,
Algorithm 2): pyramidal Lucas-Kanade flow on strong corners between consecutive greyscale
frames of the downward camera, summed by direction from the image centre, with the variance of
the m x m segment sums as a gate against the even expansion of flat ground.

A leaf package: numpy and OpenCV only.
"""

from avoidance.optical_flow import (
    DIRECTIONS,
    FlowSettings,
    ObstacleReport,
    analyse,
    calibrate,
    direction_sums,
    segment_sums,
    sparse_flow,
)

__all__ = [
    "DIRECTIONS",
    "FlowSettings",
    "ObstacleReport",
    "analyse",
    "calibrate",
    "direction_sums",
    "segment_sums",
    "sparse_flow",
]
