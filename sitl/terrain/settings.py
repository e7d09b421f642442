"""Validated settings of the terrain worlds (pydantic v2).

:data:`TerrainSettings` is a discriminated union on ``kind``; parse a plain mapping (e.g.
from mission YAML) with :func:`parse_terrain_settings`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    TypeAdapter,
    field_validator,
    model_validator,
)

# Larger grids would not fit comfortably in a laptop's memory (float32 + work arrays).
MAX_CELLS = 64_000_000
MAX_EXTENT = 100_000.0
"""m: the widest world, twice the 50 km a multicopter flies from home (its battery lasts
under an hour at up to about 20 m/s)."""
MAX_RELIEF = 10_000.0
"""m: heights, relief and feature sizes stay within 10 km (Olympus Mons stands 22 km over
Mars's datum, but no multicopter flies 10 km above its home)."""

Range = tuple[
    Annotated[float, Field(ge=0, le=MAX_RELIEF)], Annotated[float, Field(ge=0, le=MAX_RELIEF)]
]
"""(min, max), each 0 .. MAX_RELIEF."""



def _check_range(value: Range, name: str, low: float = 0.0) -> Range:
    lo, hi = value
    if not (low <= lo <= hi):
        raise ValueError(f"{name}: need {low} <= min <= max, got {value}")
    return value


def _size_range(value: Range, name: str) -> Range:
    """A (min, max) size in metres: 0 < min <= max."""
    if value[0] <= 0:
        raise ValueError(f"need min > 0, got {value}")
    return _check_range(value, name)


class _GridSettings(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    cell_size: float = Field(
        0.2, gt=0, le=5.0, description="simulation grid spacing (m), up to 5 m; the world "
        f"may hold at most {MAX_CELLS:,} cells (memory)"
    )
    home_clear_radius: float = Field(
        8.0, ge=0, le=MAX_EXTENT / 2, description="radius (m) around home flattened so "
        "that takeoff is safe; it must fit in the world"
    )


MAX_MOVING = 500
"""Moving obstacles of one world: each is intersected with every sensor ray of every frame."""

Point = tuple[
    Annotated[float, Field(ge=-MAX_EXTENT / 2, le=MAX_EXTENT / 2)],
    Annotated[float, Field(ge=-MAX_EXTENT / 2, le=MAX_EXTENT / 2)],
]


class MovingPathSettings(BaseModel):
    """One moving obstacle on a path given point by point."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    kind: Literal["person", "vehicle"] = Field(description="person or vehicle")
    path: list[Point] = Field(
        min_length=1, max_length=100, description="ENU (x, y) points (m) it walks through, "
        "1 .. 100; one point: it stands there"
    )
    speed: float = Field(
        0.0, ge=0, le=40, description="m/s along the path, up to 40 (a car in town drives "
        "under 15); 0: it stands at the path's first point"
    )
    closed: bool = Field(
        False, description="walk round (back to the first point) instead of back and forth"
    )
    once: bool = Field(
        False, description="walk the path once and stay at its end (e.g. someone walking "
        "onto a landing site)"
    )
    start: float = Field(
        0.0, ge=0, le=MAX_EXTENT, description="metres along the path at t = 0"
    )


class MovingObstaclesSettings(BaseModel):
    """People and vehicles walking or driving seeded paths (sitl.terrain.moving). Random
    paths draw from a stream of their own: the static world is the same with or without
    them."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    count: int = Field(
        0, ge=0, le=MAX_MOVING, description=f"random obstacles, up to {MAX_MOVING} with the "
        "given paths (every sensor ray is tested against each)"
    )
    vehicle_fraction: float = Field(
        0.3, ge=0, le=1, description="share of the random obstacles that are vehicles (the "
        "rest are people)"
    )
    person_speed: Range = Field(
        (0.8, 1.6), description="walking speed range (m/s) of random people"
    )
    vehicle_speed: Range = Field(
        (2.0, 8.0), description="driving speed range (m/s) of random vehicles"
    )
    path_length: Range = Field(
        (20.0, 120.0), description="length range (m) of a random path"
    )
    legs: int = Field(3, ge=1, le=50, description="straight legs of a random path, 1 .. 50")
    closed_fraction: float = Field(
        0.5, ge=0, le=1, description="share of random paths walked round (the rest back "
        "and forth)"
    )
    area: tuple[
        Annotated[float, Field(ge=-MAX_EXTENT / 2, le=MAX_EXTENT / 2)],
        Annotated[float, Field(ge=-MAX_EXTENT / 2, le=MAX_EXTENT / 2)],
        Annotated[float, Field(gt=0, le=MAX_EXTENT)],
    ] | None = Field(
        None, description="(x, y, radius) m: random paths start in this disc (e.g. around "
        "the landing sites); None: anywhere in the world"
    )
    person_radius: float = Field(0.3, gt=0, le=5, description="a person's footprint radius (m)")
    person_height: float = Field(1.8, gt=0, le=5, description="a person's height (m)")
    vehicle_length: float = Field(4.5, gt=0, le=30, description="a vehicle's length (m)")
    vehicle_width: float = Field(2.0, gt=0, le=10, description="a vehicle's width (m)")
    vehicle_height: float = Field(1.6, gt=0, le=10, description="a vehicle's height (m)")
    paths: list[MovingPathSettings] = Field(
        [], description="obstacles on given paths, besides the random ones"
    )

    @field_validator("person_speed", "vehicle_speed")
    @classmethod
    def _speeds(cls, v: Range, info) -> Range:
        if v[1] > 40:
            raise ValueError(f"need max <= 40 m/s, got {v}")
        return _check_range(v, info.field_name)

    @field_validator("path_length")
    @classmethod
    def _lengths(cls, v: Range, info) -> Range:
        return _size_range(v, info.field_name)

    @model_validator(mode="after")
    def _total(self):
        if self.count + len(self.paths) > MAX_MOVING:
            raise ValueError(
                f"count: {self.count} random and {len(self.paths)} given obstacles, more "
                f"than {MAX_MOVING}"
            )
        return self


class _ProceduralSettings(_GridSettings):
    size: tuple[
        Annotated[float, Field(ge=10.0, le=MAX_EXTENT)],
        Annotated[float, Field(ge=10.0, le=MAX_EXTENT)],
    ] = Field(
        (400.0, 400.0), description="extent (m) along x (east) and y (north), each 10 m .. "
        f"100 km (twice a multicopter's range); at most {MAX_CELLS:,} cells of cell_size "
        "(memory)"
    )
    center: tuple[
        Annotated[float, Field(ge=-MAX_EXTENT / 2, le=MAX_EXTENT / 2)],
        Annotated[float, Field(ge=-MAX_EXTENT / 2, le=MAX_EXTENT / 2)],
    ] = Field(
        (0.0, 0.0), description="ENU (x, y) of the terrain centre; home (0, 0) must be inside"
    )
    moving_obstacles: MovingObstaclesSettings | None = Field(
        None, description="people and vehicles moving on seeded paths (sitl.terrain.moving); "
        "None: nothing moves"
    )

    @model_validator(mode="after")
    def _fits(self):
        nx = self.size[0] / self.cell_size
        ny = self.size[1] / self.cell_size
        if nx * ny > MAX_CELLS:
            raise ValueError(
                f"cell_size: {self.size[0]} x {self.size[1]} m at {self.cell_size} m is "
                f"{nx * ny:.3g} cells, more than {MAX_CELLS}"
            )
        half_x, half_y = self.size[0] / 2, self.size[1] / 2
        # Home and its takeoff clearing must lie inside the world.
        margin = self.home_clear_radius
        if abs(self.center[0]) + margin > half_x or abs(self.center[1]) + margin > half_y:
            raise ValueError(
                f"center: home (0, 0) with its {margin} m clearing must be inside the "
                f"terrain, centre {self.center} size {self.size}"
            )
        self._moving_inside(half_x, half_y)
        return self

    def _moving_inside(self, half_x: float, half_y: float) -> None:
        """Given paths and the random paths' area lie on the world."""
        moving = self.moving_obstacles
        if moving is None:
            return

        def inside(x: float, y: float) -> bool:
            return abs(x - self.center[0]) <= half_x and abs(y - self.center[1]) <= half_y

        for i, p in enumerate(moving.paths):
            for j, (x, y) in enumerate(p.path):
                if not inside(x, y):
                    raise ValueError(
                        f"moving_obstacles.paths.{i}.path.{j}: ({x:g}, {y:g}) is off the "
                        f"world (centre {self.center}, size {self.size})"
                    )
        if moving.area is not None and not inside(*moving.area[:2]):
            raise ValueError(
                f"moving_obstacles.area: centre ({moving.area[0]:g}, {moving.area[1]:g}) is "
                f"off the world (centre {self.center}, size {self.size})"
            )


class FlatTerrainSettings(_ProceduralSettings):
    """A level plane at z = 0."""

    kind: Literal["flat"] = "flat"


class MarsTerrainSettings(_ProceduralSettings):
    """Mars-like relief: fractal terrain, craters with raised rims, rock fields, scarps."""

    kind: Literal["mars"] = "mars"
    relief_rms: float = Field(
        2.0, ge=0, le=MAX_RELIEF, description="RMS height (m) of the fractal relief, up to "
        "10 km"
    )
    relief_wavelength: float = Field(
        150.0, gt=0, le=MAX_EXTENT, description="longest wavelength (m) of the fractal "
        "relief, up to the widest world (100 km)"
    )
    relief_beta: float = Field(
        4.2, gt=1, le=6, description="power-spectrum exponent: P(k) ~ k^-beta (higher: smoother)"
    )
    crater_density: float = Field(
        150.0, ge=0, le=10_000, description="craters per km^2 with diameter >= "
        "crater_diameter[0], up to 10,000 (one per 100 m^2: saturated ground; each crater "
        "is drawn on the grid)"
    )
    crater_diameter: Range = Field(
        (5.0, 80.0), description="crater diameter range (m), within 10 km"
    )
    crater_sfd_exponent: float = Field(
        2.0, gt=0, le=10, description="q of the cumulative crater size-frequency law "
        "N(>D) ~ D^-q, up to 10 (measured laws have q of 1 to 4)"
    )
    rock_density: float = Field(
        0.2, ge=0, le=10, description="rocks per m^2 with diameter >= rock_diameter[0], in "
        "rock fields, up to 10 (rocks shoulder to shoulder at the 0.15 m default)"
    )
    rock_diameter: Range = Field((0.15, 2.5), description="rock diameter range (m), within 10 km")
    rock_sfd_exponent: float = Field(
        2.5, gt=0, le=10, description="q of the cumulative rock size-frequency law "
        "N(>D) ~ D^-q, up to 10 (measured laws have q of 1 to 4)"
    )
    rock_field_fraction: float = Field(
        0.4, ge=0, le=1, description="fraction of the area covered by rock fields"
    )
    rock_height_ratio: float = Field(0.5, gt=0, le=1.5, description="rock height / diameter")
    scarp_count: int = Field(3, ge=0, le=100, description="number of steep slopes (scarps)")
    scarp_height: Range = Field((4.0, 12.0), description="scarp height range (m), within 10 km")
    scarp_slope_deg: Range = Field((25.0, 45.0), description="scarp face slope range (deg)")

    @field_validator("crater_diameter", "rock_diameter", "scarp_height")
    @classmethod
    def _positive_range(cls, v: Range, info) -> Range:
        return _size_range(v, info.field_name)

    @field_validator("scarp_slope_deg")
    @classmethod
    def _slope_range(cls, v: Range) -> Range:
        if not (0 < v[0] <= v[1] < 90):
            raise ValueError(f"need 0 < min <= max < 90 deg, got {v}")
        return v


class UrbanTerrainSettings(_ProceduralSettings):
    """A town: flat ground, a street grid, flat-roofed buildings, trees and parked cars."""

    kind: Literal["urban"] = "urban"
    block_size: float = Field(
        80.0, gt=10, le=MAX_EXTENT, description="street-grid spacing (m), up to 100 km"
    )
    road_width: float = Field(10.0, gt=0, le=MAX_EXTENT, description="road width (m)")
    building_fraction: float = Field(
        0.45, ge=0, le=0.9, description="fraction of each block's area built over"
    )
    building_size: Range = Field(
        (8.0, 30.0), description="building footprint side range (m), within 10 km"
    )
    building_height: Range = Field(
        (3.0, 25.0), description="building height range (m), within 10 km"
    )
    rooftop_clutter: float = Field(
        0.5, ge=0, le=1, description="probability that a roof carries a rooftop unit"
    )
    tree_density: float = Field(
        25.0, ge=0, le=10_000, description="trees per hectare of open (non-road, "
        "non-building) ground, up to 10,000 (one per m^2)"
    )
    tree_height: Range = Field((4.0, 14.0), description="tree height range (m), within 10 km")
    car_density: float = Field(
        6.0, ge=0, le=50, description="parked cars per 100 m of road, up to 50 (a 4 m car "
        "every 4 m on both sides)"
    )

    @field_validator("building_size", "building_height", "tree_height")
    @classmethod
    def _positive_range(cls, v: Range, info) -> Range:
        return _size_range(v, info.field_name)

    @model_validator(mode="after")
    def _road_fits(self):
        if self.road_width >= self.block_size:
            raise ValueError(
                f"road_width: {self.road_width} m must be less than block_size {self.block_size} m"
            )
        return self


class RubbleTerrainSettings(_ProceduralSettings):
    """A collapsed-structure field: debris piles and scattered blocks, a few flat slabs."""

    kind: Literal["rubble"] = "rubble"
    pile_density: float = Field(
        40.0, ge=0, le=10_000, description="debris piles per hectare, up to 10,000 (one "
        "per m^2)"
    )
    pile_radius: Range = Field((4.0, 15.0), description="pile radius range (m), within 10 km")
    pile_height: Range = Field((0.8, 4.0), description="pile height range (m), within 10 km")
    block_density: float = Field(
        0.1, ge=0, le=10, description="debris blocks per m^2 with size >= block_size[0], up "
        "to 10 (blocks side by side at the 0.2 m default)"
    )
    block_size: Range = Field(
        (0.2, 2.0), description="debris block side range (m), within 10 km"
    )
    block_sfd_exponent: float = Field(
        2.2, gt=0, le=10, description="q of N(>s) ~ s^-q for blocks, up to 10 (measured laws "
        "have q of 1 to 4)"
    )
    slab_density: float = Field(
        8.0, ge=0, le=10_000, description="flat slabs per hectare, up to 10,000 (one per m^2)"
    )
    slab_size: Range = Field((6.0, 12.0), description="slab side range (m), within 10 km")
    slab_tilt_deg: float = Field(6.0, ge=0, lt=90, description="largest slab tilt (deg)")

    @field_validator("pile_radius", "pile_height", "block_size", "slab_size")
    @classmethod
    def _positive_range(cls, v: Range, info) -> Range:
        return _size_range(v, info.field_name)


FLOAT32_MAX = 3.4028235e38
"""The largest float32: nodata values are float32 or integers in the files that hold them."""

MAX_MODEL_EXTENT = 40_075_000.0
"""m: an elevation model spans at most the Earth's circumference (a global mosaic)."""


class GeoPoint(BaseModel):
    """A point in WGS84 degrees."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    lat: float = Field(ge=-90, le=90, description="latitude, WGS84 degrees")
    lon: float = Field(ge=-180, le=180, description="longitude, WGS84 degrees")


ModelPoint = tuple[
    Annotated[float, Field(ge=0, le=MAX_MODEL_EXTENT)],
    Annotated[float, Field(ge=0, le=MAX_MODEL_EXTENT)],
]
"""(x, y) metres from an elevation model's south-west corner, up to the Earth's
circumference."""


def _point_kind(value: Any) -> str:
    return "geo" if isinstance(value, (Mapping, GeoPoint)) else "model"


class WindowSettings(BaseModel):
    """The area of a large elevation model to fly over: only it is read and made a world."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    center: Annotated[
        Annotated[GeoPoint, Tag("geo")] | Annotated[ModelPoint, Tag("model")],
        Discriminator(_point_kind),
    ] | None = Field(
        None, description="the window's centre: {lat, lon} in WGS84 degrees (a model with a "
        "coordinate system) or [x, y] metres from the model's south-west corner; None: the "
        "model's centre"
    )
    size: tuple[
        Annotated[float, Field(gt=0, le=MAX_EXTENT)], Annotated[float, Field(gt=0, le=MAX_EXTENT)]
    ] = Field(
        description="width (east) and depth (north) of the window, metres, each up to 100 km "
        f"(the widest world); at most {MAX_CELLS:,} cells of cell_size, and of the model, "
        "are read (memory)"
    )


class FileTerrainSettings(_GridSettings):
    """A real elevation model from a file, resampled to the simulation grid.

    Formats: ``.npy`` (2-D array, row i along +y i.e. south to north, needs
    ``source_cell_size``), ESRI ASCII grid ``.asc`` (north-up, header gives the cell size),
    GeoTIFF ``.tif``/``.tiff`` and the other DEM formats GDAL reads (SRTM ``.hgt``, DTED,
    ``.img``, ``.bil``, ``.flt``, ``.vrt``; they need the optional ``geotiff`` extra, rasterio
    and pyproj; the CRS and units are converted to metres, see :mod:`sitl.terrain.geotiff`).
    """

    kind: Literal["file"] = "file"
    path: Path = Field(description="elevation model file")
    source_cell_size: float | None = Field(
        None, gt=0, le=1000, description="cell size (m) of a .npy file (others carry their "
        "own), up to 1 km"
    )
    home: Annotated[
        Annotated[GeoPoint, Tag("geo")]
        | Annotated[
            tuple[Annotated[float, Field(ge=0, le=MAX_EXTENT)],
                  Annotated[float, Field(ge=0, le=MAX_EXTENT)]],
            Tag("model"),
        ],
        Discriminator(_point_kind),
    ] | None = Field(
        None,
        description="home on the model: {lat, lon} in WGS84 degrees (a model with a "
        "coordinate system) or (x, y) in metres from the model's south-west corner (its "
        "window's when one is given); None = the centre of the model or window (a mission "
        "that gives its home places it at that home on a model with a coordinate system)",
    )
    nodata: float | None = Field(
        None, ge=-FLOAT32_MAX, le=FLOAT32_MAX, description="height value, in the file's own "
        "unit, that marks unknown cells in a model that does not tag its nodata (e.g. -9999, "
        "-32768 or -3.4028235e38, float32's range); the file's own nodata is always honoured"
    )
    window: WindowSettings | None = Field(
        None, description="the area of the model to fly over, read alone from a large model "
        "(a whole DEM tile); None: the whole model"
    )
    vertical_scale: float = Field(
        1.0, gt=0, le=1000, description="factor applied to the heights, up to 1000"
    )
    moving_obstacles: MovingObstaclesSettings | None = Field(
        None, description="people and vehicles on given paths (sitl.terrain.moving; random "
        "ones need a generated world: count must be 0), each point on the model; None: "
        "nothing moves"
    )

    @field_validator("path")
    @classmethod
    def _readable(cls, v: Path) -> Path:
        from sitl.terrain.geotiff import GDAL_SUFFIXES

        suffix = v.suffix.lower()
        if suffix not in (".npy", ".asc", *GDAL_SUFFIXES):
            raise ValueError(
                f"unsupported format {suffix!r} (use {', '.join(('.npy', '.asc', *GDAL_SUFFIXES))})"
            )
        if not v.is_file():
            raise ValueError(f"no such file: {v}")
        return v

    @model_validator(mode="after")
    def _npy_cell(self):
        if self.path.suffix.lower() == ".npy" and self.source_cell_size is None:
            raise ValueError("source_cell_size: required for a .npy elevation model")
        from sitl.terrain.files import check_elevation

        check_elevation(self)  # readable, a grid, the window on it, fits MAX_CELLS, home inside
        self._moving_on_model()
        return self

    def _moving_on_model(self) -> None:
        """Moving obstacles on an elevation model: given paths only, on the model."""
        moving = self.moving_obstacles
        if moving is None:
            return
        if moving.count:
            raise ValueError(
                f"moving_obstacles.count: {moving.count} random obstacles need a generated "
                "world; on an elevation model give each one's path (moving_obstacles.paths)"
            )
        from sitl.terrain.files import model_extent

        xmin, xmax, ymin, ymax = model_extent(self)
        for i, p in enumerate(moving.paths):
            for j, (x, y) in enumerate(p.path):
                if not (xmin <= x <= xmax and ymin <= y <= ymax):
                    raise ValueError(
                        f"moving_obstacles.paths.{i}.path.{j}: ({x:g}, {y:g}) is off the "
                        f"elevation model (x {xmin:g} .. {xmax:g}, y {ymin:g} .. {ymax:g} m "
                        "about home)"
                    )


TerrainSettings = Annotated[
    FlatTerrainSettings
    | MarsTerrainSettings
    | UrbanTerrainSettings
    | RubbleTerrainSettings
    | FileTerrainSettings,
    Field(discriminator="kind"),
]
"""Settings of any terrain kind, discriminated by ``kind``."""

_ADAPTER: TypeAdapter = TypeAdapter(TerrainSettings)


def parse_terrain_settings(data: Any) -> TerrainSettings:
    """Validate a mapping such as ``{"kind": "mars", "rock_density": 0.05}`` (or pass a
    settings model through). Raises pydantic.ValidationError naming the bad field."""
    if isinstance(data, BaseModel):
        return data  # type: ignore[return-value]
    return _ADAPTER.validate_python(data)
