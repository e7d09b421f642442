"""Settings of the descent watch's camera and obstacle analyser (``perception.descent_flow``),
apart from :mod:`autonomy.perception.descent_flow` so that reading a mission does not load
OpenCV."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pydantic import BaseModel, ConfigDict, Field

from sitl.sensors.intensity import IntensityCameraSettings

if TYPE_CHECKING:
    from avoidance import FlowSettings


class DescentFlowSettings(BaseModel):
    """The descent camera and the obstacle analyser's thresholds (Algorithm 2).

    O_T and V_T depend on the camera, the frame rate and the descent speed: derive them for
    a world with :func:`calibrate_descent` (``lander flow-calibrate``), see
    docs/obstacle-avoidance.md.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    rate: float = Field(
        5.0, ge=0.1, le=100, description="frames per second during the descent, Hz, 0.1 .. "
        "100 (at most one per tick); the thresholds are per frame pair at this rate"
    )
    obstacle_threshold: float = Field(
        25.0, ge=0, le=1e6, description="O_T: excess expansion (flow over flat ground's at "
        "the measured height, less 1) summed over a direction's corners, above which that "
        "direction may hold an obstacle, 0 .. 1e6"
    )
    variance_threshold: float = Field(
        35.0, ge=0, le=1e12, description="V_T: variance of the m x m segment sums of excess "
        "expansion above which a direction's sum counts, 0 .. 1e12"
    )
    min_drop: float = Field(
        0.02, gt=0, le=100, description="m the camera must descend between two frames for "
        "them to be compared (no verdict while it hovers), up to 100 m"
    )
    segments: int = Field(3, ge=1, le=15, description="m of the m x m image segments, 1 .. 15")
    centre_radius: float = Field(
        0.15, ge=0, le=1, description="share of the half diagonal around the image centre "
        "whose corners count in no direction (straight below), 0 .. 1"
    )
    max_corners: int = Field(
        300, ge=10, le=20_000, description="most corners tracked per frame, 10 .. 20,000"
    )
    min_distance: int = Field(
        10, ge=1, le=1000, description="px between corners, 1 .. 1000 (well spaced corners "
        "cover the segments and directions as evenly as many crowded ones; scale it with the "
        "image: 10 px at 320 px wide, 5 at 160)"
    )
    corner_level: int = Field(
        1, ge=0, le=3, description="image pyramid level the corners are found on, 0 .. 3 "
        "(0: the full image; 1: half its width, four times cheaper); they are tracked at "
        "full resolution"
    )
    width: int = Field(320, ge=16, le=4096, description="image width (px), 16 .. 4096")
    height: int = Field(240, ge=16, le=4096, description="image height (px), 16 .. 4096")
    focal_px: float = Field(
        160.0, ge=1, le=100_000, description="focal length (px), 1 .. 100,000 (160 px: a "
        "90 deg view across 320 px)"
    )
    intensity: IntensityCameraSettings = IntensityCameraSettings()

    def flow(self) -> FlowSettings:
        """The analyser's settings."""
        from avoidance import FlowSettings

        # An 11 px window and 10 iterations track the descent's flow within 0.1 px (median;
        # p95 0.45 px) of a 21 px window's and 30 iterations' (benchmarks/bench_flow.py), at a
        # third of the cost.
        return FlowSettings(
            max_corners=self.max_corners, min_distance=self.min_distance,
            corner_level=self.corner_level, window=11, iterations=10, epsilon=0.03,
            segments=self.segments,
            centre_radius=self.centre_radius, obstacle_threshold=self.obstacle_threshold,
            variance_threshold=self.variance_threshold,
        )
