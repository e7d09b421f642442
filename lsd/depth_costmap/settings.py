"""Validated settings of the depth-image costmap detector (Mittal et al., section III-B).

Defaults are the paper's simulation values (c = 0.05/0.4/0.4/0.15, threshold 0.72,
theta_th = 15 deg, clustering 0.5 m / 0.01 m); its real-world stereo values were
c = 0.15/0.35/0.4/0.1, threshold 0.7 and a 0.05 m z threshold. Over noisy depth (SfM at
cruise altitude) raise ``cluster_dz`` to the depth noise.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field, model_validator


class CostmapWeights(BaseModel):
    """c1..c4 of eq. 7: each in [0, 1], summing to 1."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    depth_accuracy: float = Field(0.05, ge=0, le=1, description="c1, J_DE")
    flatness: float = Field(0.4, ge=0, le=1, description="c2, J_FL")
    steepness: float = Field(0.4, ge=0, le=1, description="c3, J_N")
    energy: float = Field(0.15, ge=0, le=1, description="c4, J_EC")

    @model_validator(mode="after")
    def _sum_to_one(self) -> CostmapWeights:
        total = self.depth_accuracy + self.flatness + self.steepness + self.energy
        if abs(total - 1.0) > 1e-6:
            raise ValueError(f"flatness: the costmap weights must sum to 1, got {total:g}")
        return self


class DepthCostmapSettings(BaseModel):
    """Costmaps, thresholds, footprint, de-duplication and clustering parameters."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    weights: CostmapWeights = CostmapWeights()
    threshold: float = Field(0.72, ge=0, le=1, description="decision-map score to be a site")
    theta_th_deg: float = Field(15.0, gt=0, lt=90, description="steepness scale (deg), eq. 5")
    d_min: float = Field(0.05, ge=0, le=100_000, description="nearest valid depth (m)")
    d_max: float = Field(
        200.0, gt=0, le=100_000, description="farthest valid depth (m), up to 100 km"
    )
    vehicle_radius: float = Field(
        1.0,
        gt=0,
        le=100,
        description="footprint radius checked (m): our vehicle's, as the elevation map's "
        "footprint_radius and the ground truth's (the paper's UAV was 0.26 m across)",
    )
    clearance_margin: float = Field(
        1.5,
        ge=0,
        le=100,
        description="beyond the paper: depth edges (obstacles, drops) must also be this much "
        "beyond the footprint (m); the image border need only clear the footprint itself, so "
        "the verification look from a few metres still fits. 0: the paper's check alone. The "
        "default matches the ground truth, which judges each cell of the 1.5 m clearance disk "
        "against its own 1 m footprint plane, so a roof edge counts up to 2.5 m away",
    )
    edge_step: float = Field(
        0.15,
        gt=0,
        le=1000,
        description="smallest depth discontinuity (m) that is an edge of the flatness map "
        "(Canny's high threshold on a noise-free depth map; the low one is edge_low_ratio of it)",
    )
    edge_noise_factor: float = Field(
        6.0,
        ge=0,
        le=1000,
        description="Canny's high threshold is at least this many times the frame's depth "
        "gradient noise (robust estimate from the image itself), so noisy depth (stereo, SfM) "
        "does not turn every pixel into an edge; 0: the edge_step alone",
    )
    edge_low_ratio: float = Field(
        0.5, gt=0, le=1, description="Canny hysteresis: low threshold / high threshold"
    )
    edge_blur_px: int = Field(
        2,
        ge=0,
        le=15,
        description="Gaussian blur radius (px) of the depth map before its gradients (Canny's "
        "own smoothing, the 5 x 5 Gaussian of the classic detector); 0: none",
    )
    normal_window: int = Field(
        5, ge=1, le=4096, description="smallest box window (px) averaging the 3D gradients "
        "of the normals, up to the largest image side"
    )
    normal_span: float = Field(
        0.5,
        ge=0,
        le=1000,
        description="ground span (m) of the normal window at the frame's median depth: the "
        "window is max(normal_window, f * normal_span / D) px (depth-dependent smoothing of "
        "integral-image normals, the paper's ref. [27]); 0: normal_window alone",
    )
    site_spacing: float = Field(
        0.3,
        gt=0,
        le=1000,
        description="ground spacing (m) of the dense sites: candidate pixels are sampled every "
        "f * site_spacing / D pixels (D the frame's median depth, at least 1 px); keep it below "
        "cluster_distance / sqrt(2) so neighbouring sites link, and above dedup_distance",
    )
    site_stride: int | None = Field(
        None, ge=1, le=4096, description="fixed pixel stride of the dense sites instead of "
        "site_spacing, up to the largest image side"
    )
    max_dense_sites: int = Field(
        5000, ge=1, le=1_000_000, description="most dense sites per frame (the stride grows "
        "to fit), up to a million"
    )
    dedup_distance: float = Field(
        0.2, ge=0, le=1000, description="a site with a listed neighbour this close (m) is not "
        "added"
    )
    cluster_distance: float = Field(
        0.5, gt=0, le=1000, description="clustering euclidean threshold (m)"
    )
    cluster_dz: float = Field(
        0.01, gt=0, le=1000, description="clustering z-difference threshold (m)"
    )
    hierarchy_limit: int = Field(
        1000,
        ge=2,
        le=10_000,
        description="lists up to this size use scipy.cluster.hierarchy; larger ones the "
        "equivalent k-d tree single-linkage components (O(n log n) instead of O(n^2)); at "
        "most 10,000, whose condensed distance matrix already takes 400 MB",
    )
    max_sites: int = Field(
        200_000, ge=1, le=10_000_000, description="most sites in the global list, up to 10 "
        "million (memory)"
    )
    sigma_ref: float = Field(
        1.0, gt=0, le=1000, description="depth 1-sigma (m) that counts as uncertainty 1"
    )
    obstacle_margin: float = Field(
        0.5, ge=0, le=1000, description="extra radius (m) searched for the obstacle altitude"
    )

    @model_validator(mode="after")
    def _ranges(self) -> DepthCostmapSettings:
        if self.d_max <= self.d_min:
            raise ValueError(f"d_max: {self.d_max} must exceed d_min ({self.d_min})")
        return self

    @property
    def theta_th(self) -> float:
        """Steepness scale, radians."""
        return math.radians(self.theta_th_deg)
