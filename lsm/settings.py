"""Validated settings of the Landing Site Manager (pydantic v2)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field


class LossWeights(BaseModel):
    """Weights of the landing-site loss (thesis eq. 3.1) and its distance normaliser.

    L = dist * d/D + rough * roughness + var * uncertainty - size * size/size_max
        + ver_alt * verification_altitude/D
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    dist: float = Field(1.0, ge=0, description="weight of horizontal distance drone -> site")
    rough: float = Field(1.0, ge=0, description="weight of roughness")
    var: float = Field(1.0, ge=0, description="weight of uncertainty")
    size: float = Field(1.0, ge=0, description="weight of size (enters with a negative sign)")
    ver_alt: float = Field(1.0, ge=0, description="weight of the verification altitude")
    normaliser: float = Field(
        100.0, gt=0, description="D: distance normaliser, the cruise altitude in metres"
    )


class LsmSettings(BaseModel):
    """Capacity, matching and verification rules of the Landing Site Manager."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    capacity: int = Field(100, ge=1, description="most sites retained")
    match_radius: float = Field(
        2.0, gt=0, description="an observation this close (horizontally, m) is the same site"
    )
    max_distance: float = Field(
        100.0, gt=0, description="sites farther than this from the drone (m) fall off"
    )
    ban_radius: float = Field(3.0, ge=0, description="radius of the zone a ban rejects (m)")
    verification_altitude: float = Field(
        2.5, gt=0, description="altitude above the site (m) at which a site counts as verified"
    )
    verification_tolerance: float = Field(
        1.0, ge=0, description="slack added to the verification altitude (m)"
    )
    rekey_distance: float = Field(
        5.0, gt=0, description="drone motion (m) after which heap keys are recomputed"
    )
