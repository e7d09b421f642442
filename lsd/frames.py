"""Sensor data as the detectors take it: plain arrays plus the camera model.

Conventions: the world frame is local ENU metres. A camera pose is the camera centre in the
world frame and the rotation camera -> world. The camera frame is the usual pinhole one:
x right, y down, z along the optical axis; pixel (u, v) = (column, row).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics in pixels."""

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int


@dataclass(frozen=True)
class DepthFrame:
    """One depth image with its per-pixel 1-sigma depth error and the camera pose.

    Attributes:
        depth: (H, W) float32, metres along the optical axis; NaN or <= 0 = no depth.
        sigma: (H, W) float32, 1-sigma depth error in metres (thesis eq. 3.2), or None.
        intrinsics: the camera's :class:`Intrinsics`.
        position: (3,) camera centre, ENU metres.
        rotation: (3, 3) rotation camera frame -> world frame.
        timestamp: clock seconds.
        source: depth source, e.g. ``"sfm"`` or ``"stereo"``.
        rendered: (H, W) bool pixels the camera measured when it was asked for only part
            of the view (the others are NaN and are neither counted nor dropped), or None.
    """

    depth: np.ndarray
    sigma: np.ndarray | None
    intrinsics: Intrinsics
    position: np.ndarray
    rotation: np.ndarray
    timestamp: float = 0.0
    source: str = ""
    rendered: np.ndarray | None = None

    def to_points(self) -> tuple[np.ndarray, np.ndarray]:
        """Back-project valid pixels to world points.

        Returns:
            points: (N, 3) float64 ENU metres of the pixels with finite positive depth.
            sigma: (N,) float64 1-sigma error of each point along the ray (zeros if the
            frame has no sigma).
        """
        k = self.intrinsics
        depth = np.asarray(self.depth, dtype=np.float64)
        valid = np.isfinite(depth) & (depth > 0)
        v, u = np.nonzero(valid)
        z = depth[v, u]
        xn = (u - k.cx) / k.fx
        yn = (v - k.cy) / k.fy
        rotation = np.asarray(self.rotation, dtype=np.float64)
        position = np.asarray(self.position, dtype=np.float64)
        # One axis at a time: a (N, 3) @ (3, 3) product would go through multi-threaded
        # BLAS, which costs more than it saves on a busy machine.
        points = np.empty((len(z), 3))
        for axis in range(3):
            r = rotation[axis]
            points[:, axis] = z * (r[0] * xn + r[1] * yn + r[2]) + position[axis]
        if self.sigma is None:
            sigma = np.zeros(len(z))
        else:
            sigma = np.asarray(self.sigma, dtype=np.float64)[v, u]
        return points, sigma
