"""Optical-flow obstacle analysis of a descending downward camera (Lee et al. 2019, Algorithm 2).

Between two consecutive greyscale frames:

1. *Magnitude map* (4.2.1): strong corners of the first frame (OpenCV ``goodFeaturesToTrack``)
   tracked into the second by the iterative pyramidal Lucas-Kanade method
   (``calcOpticalFlowPyrLK``); each tracked corner gives a flow magnitude in pixels per frame.
2. *Metric* (4.2.2): the magnitudes are summed per direction from the image centre (eight
   45 deg sectors), so a direction's sum grows with both the number of corners and their flow:
   obstacles are textured (many corners) and closer than the ground (larger flow).
3. *Gate*: over flat ground a descent expands the image evenly, so every direction's sum can
   be large; the variance of the sums over the m x m image segments is large only when one
   part of the image moves much more than the rest. A direction holds an obstacle when its
   sum exceeds ``O_T`` and the segment variance exceeds ``V_T``.

Speed: tracking costs in proportion to the corners and the window's area, and the corner
response over the whole image is the next costliest step. :class:`FlowSettings`' defaults are
thorough (2000 corners, 21 px window); the descent watch
(:meth:`autonomy.perception.descent_flow_settings.DescentFlowSettings.flow`) finds a few
hundred well-spaced corners on the first pyramid level (a quarter of the pixels) and tracks
them at full resolution with a smaller window, 300+ pairs per second at 320 x 240 on one core.

Image axes: x to the right, y up (row numbers grow downward; they are flipped here), angles
counter-clockwise from +x. Both thresholds depend on the camera (resolution, field of view,
frame rate) and the descent speed: :func:`calibrate` derives them from frames of an
obstacle-free descent.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

DIRECTIONS = (
    "right", "upper right", "up", "upper left", "left", "lower left", "down", "lower right",
)
"""The eight directions of Algorithm 2, sector i centred on i * 45 deg from the image's +x."""


@dataclass(frozen=True, slots=True)
class FlowSettings:
    """Feature tracking and the obstacle thresholds.

    Attributes:
        max_corners: most corners tracked per frame.
        quality: corner quality relative to the best corner (goodFeaturesToTrack).
        min_distance: pixels between corners (full-resolution pixels).
        corner_level: pyramid level the corners are found on (0: the full image; 1: half
            its width and height, four times cheaper); they are tracked at full resolution.
        window: Lucas-Kanade window side, pixels.
        levels: pyramid levels above the full image.
        iterations, epsilon: Lucas-Kanade stops after this many iterations per level or when
            an update moves less than ``epsilon`` pixels.
        segments: m of the m x m segments (3 in the paper).
        centre_radius: share of the half diagonal around the centre whose corners belong to
            no direction (straight below the vehicle), 0..1.
        obstacle_threshold: O_T, pixels per frame summed over a direction's corners.
        variance_threshold: V_T, variance of the m x m segment sums, (pixels per frame)^2.
    """

    max_corners: int = 2000
    quality: float = 0.01
    min_distance: int = 5
    corner_level: int = 0
    window: int = 21
    levels: int = 3
    iterations: int = 30
    epsilon: float = 0.01
    segments: int = 3
    centre_radius: float = 0.15
    obstacle_threshold: float = 60.0
    variance_threshold: float = 40.0


@dataclass(frozen=True, slots=True)
class ObstacleReport:
    """What Algorithm 2 concluded from one pair of frames.

    Attributes:
        points: (N, 2) float32 pixel positions (column, row) of the tracked corners.
        flow: (N, 2) float32 their displacement, pixels (columns, rows).
        directions: (8,) float64 summed magnitudes per direction (:data:`DIRECTIONS`).
        segments: (m, m) float64 summed magnitudes per image segment, row-major from the top.
        variance: variance of ``segments``.
        flagged: (8,) bool, the directions that hold an obstacle.
    """

    points: np.ndarray
    flow: np.ndarray
    directions: np.ndarray
    segments: np.ndarray
    variance: float
    flagged: np.ndarray

    @property
    def obstacle(self) -> bool:
        return bool(self.flagged.any())

    @property
    def away(self) -> np.ndarray:
        """(2,) unit vector in image axes (x right, y up) pointing away from the flagged
        directions, weighted by their sums; zeros when nothing is flagged or they cancel."""
        angles = np.arange(8) * (np.pi / 4)
        weights = np.where(self.flagged, self.directions, 0.0)
        toward = np.array([np.sum(weights * np.cos(angles)), np.sum(weights * np.sin(angles))])
        norm = float(np.hypot(*toward))
        return -toward / norm if norm > 1e-9 else np.zeros(2)


def _grey(frame: np.ndarray) -> np.ndarray:
    frame = np.asarray(frame)
    if frame.ndim != 2:
        raise ValueError(f"expected a greyscale (H, W) frame, got shape {frame.shape}")
    if frame.dtype == np.uint8:
        return frame
    finite = np.nan_to_num(frame.astype(np.float64), nan=0.0)
    return np.clip(finite * (255.0 if finite.max() <= 1.0 else 1.0), 0, 255).astype(np.uint8)


def _corners(frame: np.ndarray, s: FlowSettings) -> np.ndarray | None:
    """(N, 1, 2) float32 goodFeaturesToTrack corners in full-resolution pixels, or None."""
    level = frame
    for _ in range(s.corner_level):
        if min(level.shape) < 32:
            break  # too small to halve again and still hold corners
        level = cv2.pyrDown(level)
    scale = frame.shape[1] / level.shape[1]
    corners = cv2.goodFeaturesToTrack(level, s.max_corners, s.quality,
                                      max(1.0, s.min_distance / scale))
    if corners is None or scale == 1:
        return corners
    # Pixel centres: (u + 0.5) * scale - 0.5 at full resolution.
    return ((corners + 0.5) * scale - 0.5).astype(np.float32)


def sparse_flow(
    previous: np.ndarray, current: np.ndarray, settings: FlowSettings | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Corners of ``previous`` and their displacement into ``current``.

    Args:
        previous, current: (H, W) greyscale frames, uint8 or float in [0, 1].

    Returns:
        points (N, 2) float32 (column, row) and flow (N, 2) float32 pixels; corners that
        were lost between the frames are dropped.
    """
    s = settings or FlowSettings()
    a, b = _grey(previous), _grey(current)
    if a.shape != b.shape:
        raise ValueError(f"frames differ in shape: {a.shape} and {b.shape}")
    corners = _corners(a, s)
    if corners is None:
        empty = np.zeros((0, 2), np.float32)
        return empty, empty
    tracked, status, _ = cv2.calcOpticalFlowPyrLK(
        a, b, corners, None, winSize=(s.window, s.window), maxLevel=s.levels,
        criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, s.iterations, s.epsilon),
    )
    ok = status.ravel() == 1
    points = corners.reshape(-1, 2)[ok]
    return points, tracked.reshape(-1, 2)[ok] - points


def direction_sums(
    points: np.ndarray, magnitude: np.ndarray, shape: tuple[int, int], centre_radius: float
) -> np.ndarray:
    """(8,) summed ``magnitude`` of the points in each 45 deg sector around the image centre;
    points within ``centre_radius`` of the half diagonal count in none."""
    h, w = shape
    dx = points[:, 0] - (w - 1) / 2.0
    dy = (h - 1) / 2.0 - points[:, 1]  # y up
    outside = np.hypot(dx, dy) > centre_radius * np.hypot(w, h) / 2.0
    sector = np.round(np.arctan2(dy, dx) / (np.pi / 4)).astype(np.int64) % 8
    return np.bincount(sector[outside], weights=magnitude[outside], minlength=8)


def segment_sums(
    points: np.ndarray, magnitude: np.ndarray, shape: tuple[int, int], m: int
) -> np.ndarray:
    """(m, m) summed ``magnitude`` of the points in each of the m x m image segments."""
    h, w = shape
    row = np.clip((points[:, 1] * m / h).astype(np.int64), 0, m - 1)
    col = np.clip((points[:, 0] * m / w).astype(np.int64), 0, m - 1)
    return np.bincount(row * m + col, weights=magnitude, minlength=m * m).reshape(m, m)


def analyse(
    previous: np.ndarray, current: np.ndarray, settings: FlowSettings | None = None
) -> ObstacleReport:
    """Algorithm 2 on one pair of consecutive frames (see the module's docstring)."""
    s = settings or FlowSettings()
    points, flow = sparse_flow(previous, current, s)
    magnitude = np.hypot(flow[:, 0], flow[:, 1]).astype(np.float64)
    shape = np.asarray(previous).shape
    directions = direction_sums(points, magnitude, shape, s.centre_radius)
    segments = segment_sums(points, magnitude, shape, s.segments)
    variance = float(segments.var())
    flagged = (directions > s.obstacle_threshold) & (variance > s.variance_threshold)
    return ObstacleReport(points, flow, directions, segments, variance, flagged)


def calibrate(
    pairs, settings: FlowSettings | None = None, margin: float = 1.25
) -> tuple[float, float]:
    """Thresholds (O_T, V_T) from frame pairs of an obstacle-free descent: the largest
    direction sum and segment variance seen, times ``margin``.

    Args:
        pairs: iterable of (previous, current) greyscale frames over flat, open ground at the
            descent speed and frame rate the thresholds are for.
    """
    s = settings or FlowSettings()
    worst_sum = worst_var = 0.0
    seen = 0
    for previous, current in pairs:
        report = analyse(previous, current, s)
        worst_sum = max(worst_sum, float(report.directions.max()))
        worst_var = max(worst_var, report.variance)
        seen += 1
    if seen == 0:
        raise ValueError("calibrate needs at least one pair of frames")
    return worst_sum * margin, worst_var * margin
