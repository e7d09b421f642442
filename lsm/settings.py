"""Validated settings of the Landing Site Manager (pydantic v2)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

MAX_SITES = 100_000
"""Most sites the LSM may retain: its arrays are allocated for ``capacity`` at once (about
500 bytes a site, so 50 MB here) and ``ranked()`` sorts them all (about 20 ms for 100,000
on a laptop core, several ticks of the tree); a detector reports tens of sites a frame."""
MAX_DISTANCE = 50_000.0
"""m: a multicopter's battery takes it at most some 35 km out and back, so no site, match
or ban zone is farther or larger than 50 km (the missions' own bound from home)."""
MAX_ALTITUDE = 10_000.0
"""m: the highest a multicopter flies (the missions' bound above home)."""
MAX_WEIGHT = 1_000.0
"""Loss weights are relative: each term of the loss is of order one, so a ratio of 1000
between two weights already makes the smaller one irrelevant."""


class LossWeights(BaseModel):
    """Weights of the landing-site loss (thesis eq. 3.1) and its distance normaliser.

    L = dist * d/D + rough * roughness + var * uncertainty - size * size/size_max
        + ver_alt * verification_altitude/D
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    dist: float = Field(
        1.0, ge=0, le=MAX_WEIGHT, description="weight of horizontal distance drone -> site, "
        "0..1000 (weights are relative)"
    )
    rough: float = Field(1.0, ge=0, le=MAX_WEIGHT, description="weight of roughness, 0..1000")
    var: float = Field(1.0, ge=0, le=MAX_WEIGHT, description="weight of uncertainty, 0..1000")
    size: float = Field(
        1.0, ge=0, le=MAX_WEIGHT, description="weight of size (enters with a negative sign), "
        "0..1000"
    )
    ver_alt: float = Field(
        1.0, ge=0, le=MAX_WEIGHT, description="weight of the verification altitude, 0..1000"
    )
    normaliser: float = Field(
        100.0, ge=1, le=MAX_ALTITUDE, description="D: distance normaliser, the cruise "
        "altitude in metres: 1 m .. 10 km (a multicopter's ceiling)"
    )


class LsmSettings(BaseModel):
    """Capacity, matching and verification rules of the Landing Site Manager."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    capacity: int = Field(
        100, ge=1, le=MAX_SITES, description="most sites retained, 1..100,000: the LSM "
        "allocates its arrays for all of them at once (about 500 bytes a site) and ranks "
        "them all on every ranking"
    )
    match_radius: float = Field(
        2.0, ge=0.01, le=MAX_DISTANCE, description="an observation this close "
        "(horizontally, m) is the same site: 1 cm (finer than any detector places a site; "
        "sites are hashed in cells of twice this) .. 50 km (a multicopter's range)"
    )
    max_distance: float = Field(
        100.0, gt=0, le=MAX_DISTANCE, description="sites farther than this from the drone "
        "(m) fall off; at most 50 km (a multicopter's range)"
    )
    ban_radius: float = Field(
        3.0, ge=0, le=MAX_DISTANCE, description="radius of the zone a ban rejects (m), at "
        "most 50 km"
    )
    verification_altitude: float = Field(
        2.5, gt=0, le=MAX_ALTITUDE, description="altitude above the site (m) at which a site "
        "counts as verified, up to 10 km (a multicopter's ceiling)"
    )
    verification_tolerance: float = Field(
        1.0, ge=0, le=MAX_ALTITUDE, description="slack added to the verification altitude "
        "(m), up to 10 km"
    )
    rekey_distance: float = Field(
        5.0, gt=0, le=MAX_DISTANCE, description="drone motion (m) after which heap keys are "
        "recomputed, at most 50 km"
    )
