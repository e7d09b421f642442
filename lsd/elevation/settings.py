"""Validated settings of the elevation-map landing-site detector (pydantic v2).

Lengths are metres, times clock seconds. Angles are degrees here (they come from YAML) and
radians in the code that uses them (see the ``*_rad`` properties).
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field, model_validator

MAX_MAP_CELLS = 2048
"""Cells along a side of an elevation grid: a 2048 x 2048 grid of several float64 layers
takes hundreds of MB, and each frame's analysis runs over all of it."""


class ElevationMapSettings(BaseModel):
    """The robot-centric 2.5D elevation grids and how depth points are fused into them.

    Two grids: a wide, coarse one that every frame feeds and that is analysed while the
    camera is high, and a narrow, fine one (``fine_*``) that frames feed and that is
    analysed while the camera is less than ``fine_below`` above the ground, where depth is
    dense and precise enough to show rocks smaller than a coarse cell.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    size: float = Field(
        80.0, gt=0, le=10_000, description="side of the square coarse map window (m), up to "
        f"10 km; at most {MAX_MAP_CELLS} cells of resolution per side"
    )
    resolution: float = Field(0.25, gt=0, le=100, description="coarse cell side (m), up to 100")
    fine_size: float = Field(
        32.0, gt=0, le=10_000, description="side of the square fine map window (m), up to "
        f"10 km; at most {MAX_MAP_CELLS} cells of fine_resolution per side"
    )
    fine_resolution: float = Field(
        0.1, gt=0, le=100, description="fine cell side (m), up to 100"
    )
    fine_below: float = Field(
        20.0,
        ge=0,
        le=10_000,
        description="camera height above the ground (m, up to 10 km) below which the fine "
        "map is fed and analysed (0: coarse map only)",
    )
    max_age: float = Field(
        30.0, gt=0, le=3600, description="a cell not observed for this long (s, up to an "
        "hour) is forgotten"
    )
    min_range: float = Field(
        0.2, ge=0, le=100_000, description="depth below this (m) is dropped"
    )
    max_range: float = Field(
        400.0, gt=0, le=100_000, description="depth above this (m, up to 100 km) is dropped"
    )
    min_sigma: float = Field(
        0.01, gt=0, le=100, description="floor of the 1-sigma height error of one point (m)"
    )
    placement_smoothing: int = Field(
        5,
        ge=1,
        le=31,
        description="side (px) of the box over which depth is averaged to place points "
        "horizontally (1: each pixel's own depth)",
    )
    outlier_gate: float = Field(
        4.0,
        gt=0,
        le=1000,
        description="a measurement this many sigmas from the cell estimate is not fused: "
        "the estimate with the smaller variance is kept instead",
    )

    @model_validator(mode="after")
    def _check(self) -> ElevationMapSettings:
        if self.size < 4 * self.resolution:
            raise ValueError("size: must be at least 4 cells (4 * resolution)")
        if self.fine_size < 4 * self.fine_resolution:
            raise ValueError("fine_size: must be at least 4 cells (4 * fine_resolution)")
        for size, resolution, name in ((self.size, self.resolution, "size"),
                                       (self.fine_size, self.fine_resolution, "fine_size")):
            if size / resolution > MAX_MAP_CELLS:
                raise ValueError(
                    f"{name}: {size:g} m at {resolution:g} m is {size / resolution:.3g} cells "
                    f"a side, more than {MAX_MAP_CELLS} (memory: each cell holds several "
                    "float64 layers, and every frame is fused into the grid)"
                )
        if self.max_range <= self.min_range:
            raise ValueError("max_range: must be greater than min_range")
        return self

    @property
    def cells(self) -> int:
        """Number of cells along each side of the (coarse) window."""
        return int(math.ceil(self.size / self.resolution - 1e-9))

    def fine(self) -> ElevationMapSettings:
        """These settings with the fine grid's size and resolution as the grid's."""
        return self.model_copy(update={"size": self.fine_size, "resolution": self.fine_resolution})


class DetectorSettings(BaseModel):
    """Thresholds that make a cell landable and how sites are picked from the safe area.

    Emitted observations carry ``roughness = roughness_m / max_roughness`` and
    ``uncertainty = sigma_m / max_uncertainty``: both lie in [0, 1] because a site above
    either limit is not emitted (1 = just at the limit).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    footprint_radius: float = Field(
        1.0, gt=0, le=100, description="radius of the vehicle footprint (m, up to 100): "
        "plane-fit window, least size"
    )
    max_slope: float = Field(15.0, gt=0, lt=90, description="steepest landable slope (deg)")
    max_roughness: float = Field(
        0.05, gt=0, le=100, description="largest RMS residual of the footprint plane fit (m)"
    )
    max_step: float = Field(
        0.05,
        gt=0,
        le=100,
        description="largest height of a cell above or below its footprint plane (m): rocks, holes",
    )
    max_uncertainty: float = Field(
        1.5, gt=0, le=1000, description="largest RMS 1-sigma height error over the footprint (m)"
    )
    min_observed_fraction: float = Field(
        0.3, gt=0, le=1, description="least fraction of observed cells in the footprint window"
    )
    noise_tolerance: float = Field(
        3.0,
        ge=0,
        le=10_000,
        description="slope, roughness and step limits are widened by this many standard errors "
        "of the estimates, so that noisy high-altitude maps still yield (uncertain) sites; up "
        "to 10,000 (a value that large forgives every step)",
    )
    look_margin: float = Field(
        0.5,
        ge=0,
        le=100,
        description="ring beyond the footprint (m) whose cells count, with the footprint's, "
        "in a site's observation altitude: a site is only as closely seen as the ground under "
        "and around its footprint where a rock would make it unsafe (the ground truth's rotor "
        "clearance); in the fine map a step beyond max_step in this ring also makes the site "
        "doubtful",
    )
    doubtful_altitude: float = Field(
        10.0,
        ge=0,
        le=10_000,
        description="observation altitude (m) reported, at least, for a site near a step "
        "beyond max_step that only the noise tolerance forgives (in the fine map: anywhere "
        "within footprint_radius + look_margin)",
    )
    site_spacing: float = Field(
        4.0, gt=0, le=10_000, description="side of the world-aligned blocks that hold at most "
        "one site (m)"
    )
    clearance_margin: float = Field(
        1.0, ge=0, le=100, description="rotor clearance: a rock or hole this close (m) makes "
        "a cell unsafe"
    )
    obstacle_radius: float = Field(
        5.0, ge=0, le=10_000, description="radius around a site searched for the obstacle "
        "altitude (m)"
    )
    analysis_cell_ratio: float = Field(
        0.02,
        ge=0,
        le=1,
        description="while the coarse map is analysed, its cells are pooled in 2 x 2 or "
        "4 x 4 blocks (inverse-variance weighted) so that the analysed cell side grows to at "
        "most this fraction of the camera's height above the ground: far depth is too noisy "
        "for fine cells to add anything, and the analysis costs less (0: never pooled; the "
        "fine map is never pooled)",
    )
    max_analysis_pool: int = Field(
        4, ge=1, le=8, description="largest pooling factor (cells per analysed cell side)"
    )
    max_sites: int = Field(
        50, ge=1, le=100_000, description="most observations emitted per frame, up to the "
        "LSM's largest capacity"
    )
    source: str = Field(
        "elevation", max_length=100, description="prefix of the observations' source field"
    )

    @property
    def max_slope_rad(self) -> float:
        return math.radians(self.max_slope)
