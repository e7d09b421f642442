"""Validated settings of the LiDAR PCA landing-spot detector (Loureiro et al. 2021, tables 1-2).

Angles are degrees here (they come from YAML); the detector converts to radians.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator


class SpotWeights(BaseModel):
    """Weights w1..w4 of the spot grade (paper eq. 6, table 2)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    radius: float = Field(1.0, ge=0, le=1000, description="w1: accepted plane radius, 0..1000")
    slope: float = Field(1.0, ge=0, le=1000, description="w2: plane slope, 0..1000")
    sigma: float = Field(1.0, ge=0, le=1000, description="w3: z standard deviation, 0..1000")
    distance: float = Field(
        1.0, ge=0, le=1000, description="w4: horizontal distance spot -> vehicle, 0..1000"
    )

    @model_validator(mode="after")
    def _not_all_zero(self) -> SpotWeights:
        if self.radius + self.slope + self.sigma + self.distance <= 0:
            raise ValueError("radius: at least one spot weight must be positive")
        return self


class ClassRules(BaseModel):
    """What a classified cloud's ASPRS codes allow inside a site's disc and its clearance
    ring. A cloud counts as classified when it holds ground (2) points; otherwise (all 0 or
    1, or no classification) sites rest on geometry alone."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    enabled: bool = Field(True, description="use the file's classification when it has one")
    ground: list[Annotated[int, Field(ge=0, le=255)]] = Field(
        [2], max_length=256, description="classes a site may stand on and have in its "
        "clearance ring, ASPRS codes 0..255 (2: ground)"
    )
    roofs: bool = Field(
        False, description="also allow sites on flat roofs: a disc and ring of building (6) "
        "points only, with no building/non-building edge"
    )
    roof: list[Annotated[int, Field(ge=0, le=255)]] = Field(
        [6], max_length=256, description="building classes for roof sites, ASPRS codes "
        "0..255 (6: building)"
    )


class LidarPcaSettings(BaseModel):
    """Accumulation, downsampling, plane search (Algorithm 1) and grading parameters."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    travel_distance: float = Field(
        10.0, gt=0, le=50_000, description="process the accumulated cloud after this travel "
        "(m), up to 50 km"
    )
    max_cloud_points: int = Field(
        1_000_000, ge=1, le=50_000_000, description="... or when the accumulated cloud has "
        "this many points, up to 50 million (1.2 GB of float64 points)"
    )
    process_interval: float | None = Field(
        2.0,
        gt=0,
        le=3600,
        description="beyond the paper: also process after this many clock seconds without "
        "processing, so a hovering vehicle (verification) still gets fresh spots; None: off",
    )
    voxel_size: float = Field(
        0.05, ge=0.001, le=100, description="voxel-grid filter edge (m), 1 mm .. 100 m"
    )
    seeding: Literal["random", "grid"] = Field(
        "random",
        description="random: n_points random search points (the paper); grid: one search "
        "point per occupied cell of a horizontal grid covering the cloud",
    )
    n_points: int = Field(
        20, ge=1, le=100_000, description="random search points per processed cloud, up to "
        "100,000 (each is a PCA search)"
    )
    grid_spacing: float | None = Field(
        None, ge=0.01, le=1000, description="grid seeding cell (m), 0.01 .. 1000; default r_max"
    )
    n_min: int = Field(
        10, ge=3, le=1_000_000, description="fewest neighbourhood points for a PCA fit"
    )
    r_min: float = Field(
        1.5,
        gt=0,
        le=1000,
        description="first neighbourhood radius (m), the smallest spot accepted: by default "
        "our vehicle's footprint (1 m) and clearance margin (0.5 m), as the ground truth's "
        "clearance disk (the paper's tables use 0.5)",
    )
    r_max: float = Field(3.0, gt=0, le=1000, description="largest neighbourhood radius (m)")
    r_step: float = Field(
        0.5, gt=0, le=1000, description="radius increment (m); at most 1000 radii from r_min "
        "to r_max"
    )
    theta_max_deg: float = Field(15.0, gt=0, lt=90, description="steepest plane accepted (deg)")
    sigma_max: float = Field(
        0.2, gt=0, le=100, description="largest z standard deviation accepted (m; the "
        "paper's check, which a 15 deg slope over r_min already reaches: flatness is "
        "judged by residual_max)"
    )
    residual_max: float | None = Field(
        0.05, gt=0, le=100, description="beyond the paper: largest RMS distance of a "
        "neighbourhood's points from its PCA plane (m): a few centimetres for a 1 m "
        "footprint; None disables"
    )
    max_step: float | None = Field(
        0.15,
        gt=0,
        le=100,
        description="beyond the paper: stop growing when a point lies farther than this from "
        "the fitted plane (m); None disables",
    )
    max_offset: float | None = Field(
        0.15,
        gt=0,
        lt=1,
        description="beyond the paper: stop growing when the neighbourhood's horizontal "
        "centroid is farther than this fraction of the radius from the search point (the "
        "sphere runs off the data: a cloud edge or a hole); None disables",
    )
    min_spread: float | None = Field(
        0.25,
        gt=0,
        le=1,
        description="beyond the paper: stop growing when the neighbourhood's points spread "
        "across their narrowest horizontal direction less than this fraction of a filled "
        "disc's (variance r^2/4; a strip narrower than 0.87 r at 0.25): a line or strip of "
        "returns says nothing of the ground beside it; None disables",
    )
    max_gap: float | None = Field(
        2.5,
        ge=1,
        le=10,
        description="beyond the paper: a site's disc and clearance ring must be covered by "
        "returns (any class): no point of them farther than this many mean point spacings "
        "(of the disc's own returns) from a return, and the edge of the data no nearer "
        "than one spacing inside the ring; no return is unknown ground (a tile edge, water, "
        "a gap under canopy), not clear ground; None disables",
    )
    weights: SpotWeights = SpotWeights()
    distance_scale: float = Field(
        100.0, gt=0, le=50_000, description="horizontal distance (m) at which the distance "
        "grade is 0, up to 50 km"
    )
    merge_distance: float = Field(
        1.0, ge=0, le=1000, description="spots closer than this (m) are the same spot; the "
        "better stays (and discs that overlap are never both reported)"
    )
    max_spots: int = Field(
        1000, ge=1, le=100_000, description="most registered spots kept (best grades), up to "
        "the LSM's largest capacity"
    )
    obstacle_margin: float = Field(
        1.0, ge=0, le=1000, description="clearance ring: extra horizontal radius (m) "
        "around a site searched for the obstacle altitude, where no point may stand more "
        "than obstacle_height above the site's plane"
    )
    obstacle_height: float | None = Field(
        0.5, ge=0, le=1000, description="highest point allowed in the clearance ring above "
        "the site's plane (m); None: the ring only reports obstacle_altitude"
    )
    classes: ClassRules = ClassRules()

    @model_validator(mode="after")
    def _radii(self) -> LidarPcaSettings:
        if self.r_max < self.r_min:
            raise ValueError(f"r_max: {self.r_max} must be >= r_min ({self.r_min})")
        if (self.r_max - self.r_min) / self.r_step > 1000:
            raise ValueError(
                f"r_step: {self.r_step:g} m makes more than 1000 radii from r_min to r_max"
            )
        return self

    @property
    def theta_max(self) -> float:
        """Steepest accepted slope, radians."""
        return math.radians(self.theta_max_deg)

    @property
    def radii(self) -> list[float]:
        """Neighbourhood radii tried in order, r_min .. r_max in r_step (r_max included)."""
        n = int(math.floor((self.r_max - self.r_min) / self.r_step + 1e-9))
        radii = [self.r_min + i * self.r_step for i in range(n + 1)]
        if self.r_max - radii[-1] > 1e-9:
            radii.append(self.r_max)
        return radii
