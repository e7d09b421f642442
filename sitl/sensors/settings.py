"""Validated settings of the simulated sensors (pydantic v2)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field, model_validator


class RangeFinderSettings(BaseModel):
    """Downward laser range finder (along the body -z axis)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    min_range: float = Field(
        0.2, ge=0, le=1000, description="shortest reported distance (m), up to 1 km"
    )
    max_range: float = Field(
        40.0, gt=0, le=1000, description="longest reported distance (m), up to 1 km (laser "
        "range finders on multicopters reach tens to a few hundred metres)"
    )
    noise_std: float = Field(0.02, ge=0, le=100, description="1-sigma range noise (m)")

    @model_validator(mode="after")
    def _ordered(self):
        if self.min_range >= self.max_range:
            raise ValueError(
                f"max_range: {self.max_range} m must exceed min_range {self.min_range} m"
            )
        return self


class DepthCameraSettings(BaseModel):
    """Downward (nadir) pinhole depth camera with the thesis' depth error model.

    Depth error (thesis eq. 3.2): sigma_z = z^2 / (f b) * sigma_d. Structure from motion
    (``sfm``) at altitude takes the baseline b from the lateral motion over the last
    ``sfm_window`` seconds (capped at ``sfm_max_baseline``, the keyframe spacing) and gives no
    depth below ``sfm_min_baseline``; the stereo camera at low altitude has the fixed
    ``stereo_baseline``. The range finder's AGL selects the source with hysteresis: stereo
    below ``stereo_below``, SfM above ``sfm_above``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    width: int = Field(256, ge=2, le=4096, description="image width (px)")
    height: int = Field(256, ge=2, le=4096, description="image height (px)")
    focal_px: float = Field(
        256.0, ge=0.1, le=100_000, description="focal length f (px), 0.1 .. 100,000 (a "
        "field of view from almost 180 deg down to a telescope's)"
    )
    disparity_sigma_px: float = Field(
        0.5, ge=0, le=100, description="sigma_d, disparity error (px), up to 100"
    )
    noise: bool = Field(True, description="add depth noise (False: ground-truth depth)")
    max_depth: float = Field(
        1000.0, gt=0, le=100_000, description="far clip (m), up to 100 km (the widest world)"
    )
    stereo_baseline: float = Field(
        0.2, gt=0, le=100, description="stereo baseline (m), up to 100"
    )
    stereo_max_range: float = Field(
        30.0, gt=0, le=100_000, description="farthest stereo depth (m), up to 100 km"
    )
    sfm_window: float = Field(
        2.0, gt=0, le=3600, description="pose history for the SfM baseline (s), up to an hour"
    )
    sfm_min_baseline: float = Field(
        2.0, gt=0, le=10_000, description="no SfM depth below this (m), up to 10 km"
    )
    sfm_max_baseline: float = Field(
        15.0, gt=0, le=10_000, description="SfM keyframe spacing cap (m), up to 10 km"
    )
    stereo_below: float = Field(
        15.0, gt=0, le=10_000, description="switch to stereo below this AGL (m), up to 10 km "
        "(a multicopter's ceiling)"
    )
    sfm_above: float = Field(
        20.0, gt=0, le=10_000, description="switch to SfM above this AGL (m), up to 10 km"
    )
    level_of_detail: bool = Field(
        True,
        description="render from the terrain's mean-height level whose cell is nearest the "
        "pixel footprint (depth / focal_px, log2 rounded; at most 2 x 2 cells); False: "
        "always full resolution",
    )
    march_step: float | None = Field(
        None, ge=0.01, le=100, description="horizontal ray-march step (m), 0.01 .. 100 (a "
        "finer step costs time per pixel and adds nothing below the terrain cell); None: the "
        "terrain cell size"
    )

    @model_validator(mode="after")
    def _consistent(self):
        if self.sfm_above < self.stereo_below:
            raise ValueError(
                f"sfm_above: {self.sfm_above} m must be >= stereo_below {self.stereo_below} m"
            )
        if self.sfm_max_baseline < self.sfm_min_baseline:
            raise ValueError(
                f"sfm_max_baseline: {self.sfm_max_baseline} m must be >= sfm_min_baseline "
                f"{self.sfm_min_baseline} m"
            )
        return self
