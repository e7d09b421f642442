"""The mission file: its schema, loading with file:line:field errors, and overrides.

A mission file is YAML. Its schema (:class:`Mission`, pydantic v2, unknown keys forbidden)
composes the settings models each package owns: :class:`lsm.settings.LossWeights` and
:class:`lsm.settings.LsmSettings`, :class:`behaviors.settings.LandingSettings`, the terrain
settings of :mod:`sitl.terrain` and the simulator's ``SitlSettings``.

:func:`load_mission` reports every problem of a file at once, one message per problem, each
naming the file, the line and the field (``missions/x.yaml:12: landing.acceptance_radius:
Input should be greater than 0 (got -1)``). :func:`apply_overrides` sets dotted keys on a
mission (campaigns vary settings this way) and re-validates it.

Longer than 500 lines: the mission schema and its loading (YAML with line numbers, one-line
errors naming file, line and field, overrides) live together; splitting schema from loading
is the next step.
"""

from __future__ import annotations

import copy
import functools
import math
import os
import re
import stat
import typing
from collections.abc import Callable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

import numpy as np
import yaml
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    PrivateAttr,
    Tag,
    TypeAdapter,
    ValidationError,
    field_validator,
    model_validator,
)

from autonomy.errors import UserError, one_line
from autonomy.perception.descent_flow_settings import DescentFlowSettings
from autonomy.perception.scripted import ScriptedSettings, ScriptedSite
from autonomy.vehicle.connection import check_url, signing_key_from_text
from autonomy.vehicle.settings import VehicleLinkSettings
from behaviors.names import did_you_mean
from behaviors.settings import (
    MAX_ALTITUDE,
    MAX_RANGE,
    MAX_WAYPOINTS,
    Altitude,
    Horizontal,
    LandingSettings,
    MissionPlan,
)
from lsd.depth_costmap.settings import DepthCostmapSettings
from lsd.elevation.settings import DetectorSettings, ElevationMapSettings
from lsd.lidar_pca.settings import LidarPcaSettings
from lsm.area import NoFlyCircle, OperatingArea, self_intersection
from lsm.settings import LossWeights, LsmSettings
from sitl import SitlSettings
from sitl.copter import HomeSettings
from sitl.sensors import DepthCameraSettings, RangeFinderSettings
from sitl.sensors.lidar import LidarSettings
from sitl.terrain import TerrainSettings

# WGS-84, for the local tangent plane about home.
_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3

MAX_SEED = 2**32 - 1
"""Seeds are 0 .. 2**32-1: numpy's generators take non-negative integers, and every seed a
flight derives is a 32-bit word."""
MAX_TIME_LIMIT = 14_400.0
"""s: four hours, longer than any multicopter battery lasts; a lockstep flight runs
time_limit x tick_rate ticks."""
MAX_SITES = 10_000
"""Sites of the scripted source: typed by hand (a detector finds the others)."""
_ENV_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


class YamlLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):  # type: ignore[misc]
    """PyYAML's safe loader (libyaml's when installed: five times faster on big files) that
    also reads ``1e23`` as a number, as YAML 1.2 does (YAML 1.1 needs ``1.0e+23``)."""


YamlLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?[0-9][0-9_]*[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def read_yaml_value(text: str) -> Any:
    """A YAML scalar or flow value (``5``, ``1e23``, ``[1, 2]``, ``text``), as mission files
    read it. Raises yaml.YAMLError."""
    return yaml.load(text, Loader=YamlLoader)  # noqa: S506 (a safe loader)


def _flat_world() -> Any:
    return TypeAdapter(TerrainSettings).validate_python({"kind": "flat"})


HomeSource = Literal["vehicle", "file"]
Projection = Callable[[float, float, float, float], tuple[float, float]]
"""(lat, lon, lat0, lon0) degrees -> (east, north) metres of (lat, lon) from (lat0, lon0)."""


class VehicleConfig(BaseModel):
    """How to reach the vehicle; ``link`` tunes the MAVLink driver.

    On a live link lat/lon waypoints are converted about the home the vehicle reports, and a
    file ``home`` farther than ``home_tolerance`` (or ``home_altitude_tolerance``) from it
    makes the flight refuse to start unless ``home_from`` says which home to fly by:
    ``vehicle`` (lat/lon waypoints are flown to their lat/lon) or ``file`` (the mission is
    flown as drawn about the file's home, moved to the vehicle's home: lat/lon waypoints keep
    their offsets from the file's home and are not reached at their own lat/lon).
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    connection: str = Field(
        "sim://",
        max_length=1000,
        description="sim:// (embedded SITL, lockstep) or a pymavlink URL (udp:, tcp:, serial)",
    )
    autopilot: Literal["ardupilot", "px4"] = Field(
        "ardupilot", description="personality of the embedded SITL (sim:// only)"
    )
    signing_key: str | None = Field(
        None, min_length=1, max_length=1000,
        description="MAVLink 2 signing key: 64 hex digits or a passphrase",
    )
    signing_key_env: str | None = Field(
        None, max_length=200, description="name of an environment variable holding the "
        "signing key; it must be set when the mission is validated or flown",
    )
    link: VehicleLinkSettings = VehicleLinkSettings()
    home_from: HomeSource | None = Field(
        None, description="live flights whose file home and vehicle home disagree: fly by "
        "the 'vehicle' home or the 'file' home; unset = refuse to fly"
    )
    home_tolerance: float = Field(
        5.0, gt=0, le=MAX_RANGE, description="m horizontally the file's home may lie from the "
        "vehicle's, up to 50 km (a multicopter's range)"
    )
    home_altitude_tolerance: float = Field(
        10.0, gt=0, le=MAX_ALTITUDE, description="m the file's home altitude may differ from "
        "the vehicle's, up to 10 km"
    )

    @field_validator("connection")
    @classmethod
    def _known_link(cls, url: str) -> str:
        return check_url(url)

    @field_validator("signing_key")
    @classmethod
    def _key_text(cls, text: str | None) -> str | None:
        if text is not None and not text.strip():
            raise ValueError("the signing key is empty")
        return text

    @field_validator("signing_key_env")
    @classmethod
    def _key_variable(cls, name: str | None) -> str | None:
        if name is None:
            return None
        if not _ENV_NAME.match(name):
            raise ValueError(f"{name!r} is not an environment variable name")
        text = os.environ.get(name)
        if text is None:
            raise ValueError(f"environment variable {name} is not set")
        if not text.strip():
            raise ValueError(f"environment variable {name} is empty")
        return name

    @property
    def lockstep(self) -> bool:
        """True for the embedded SITL, which the runner steps in lockstep."""
        return self.connection.startswith("sim://")

    def signing_key_bytes(self) -> bytes | None:
        """The 32-byte signing key (hex as is, a passphrase hashed with SHA-256), or None.

        Raises:
            UserError: ``signing_key_env`` names a variable that is not set.
        """
        text = self.signing_key
        if text is None and self.signing_key_env is not None:
            text = os.environ.get(self.signing_key_env)
            if text is None:
                raise UserError(
                    f"vehicle.signing_key_env: environment variable {self.signing_key_env} "
                    "is not set"
                )
        return None if text is None else signing_key_from_text(text)


class GeoWaypoint(BaseModel):
    """A waypoint in geodetic coordinates (degrees); ``alt`` is metres above home."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    lat: float = Field(ge=-90, le=90, description="latitude, degrees")
    lon: float = Field(ge=-180, le=180, description="longitude, degrees")
    alt: float | None = Field(
        None, gt=0, le=MAX_ALTITUDE, description="m above home, up to 10 km (a multicopter's "
        "ceiling); default: cruise_altitude"
    )


def _waypoint_kind(value: Any) -> str:
    return "geo" if isinstance(value, (Mapping, GeoWaypoint)) else "enu"


def _within_range(wp: tuple[float, float, float]) -> tuple[float, float, float]:
    distance = math.hypot(wp[0], wp[1])
    if distance > MAX_RANGE:
        raise ValueError(f"{distance:.0f} m from home, more than the {MAX_RANGE:.0f} m a "
                         "multicopter flies")
    return wp


Waypoint = Annotated[
    Annotated[tuple[Horizontal, Horizontal, Altitude], AfterValidator(_within_range),
              Tag("enu")]
    | Annotated[GeoWaypoint, Tag("geo")],
    Discriminator(_waypoint_kind),
]
"""``[x, y, z]`` ENU metres (x, y within 50 km of home, 0 < z <= 10 km) or ``{lat, lon,
alt}``."""


class GeoVertex(BaseModel):
    """A geofence vertex in geodetic coordinates (degrees)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    lat: float = Field(ge=-90, le=90, description="latitude, degrees")
    lon: float = Field(ge=-180, le=180, description="longitude, degrees")


Vertex = Annotated[
    Annotated[tuple[Horizontal, Horizontal], Tag("enu")] | Annotated[GeoVertex, Tag("geo")],
    Discriminator(_waypoint_kind),
]
"""``[x, y]`` ENU metres about home or ``{lat, lon}``."""

MAX_FENCE_VERTICES = 1_000
"""Vertices of a geofence: autopilots store at most a few hundred fence points (ArduPilot's
FENCE_TOTAL tops out at some 80 on small boards), and the simple-polygon check is
quadratic."""


MAX_FENCE_ZONES = 100
"""No-fly zones of a mission: each is a run of fence items on the autopilot, which stores a
few hundred items at most."""

class NoFlyCircleZone(BaseModel):
    """A round no-fly zone (a mast, a tree, a person, a take-off spot): everything within
    ``radius`` m of ``centre``."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    centre: Vertex = Field(description="ENU [x, y] m or {lat, lon}, as polygon's vertices")
    radius: float = Field(gt=0, le=MAX_RANGE, description="m, up to 50 km")


def _zone_kind(value: Any) -> str:
    return "circle" if isinstance(value, (Mapping, NoFlyCircleZone)) else "polygon"


NoFlyZone = Annotated[
    Annotated[list[Vertex], Field(min_length=3, max_length=MAX_FENCE_VERTICES),
              Tag("polygon")]
    | Annotated[NoFlyCircleZone, Tag("circle")],
    Discriminator(_zone_kind),
]
"""A no-fly polygon (3 to 1000 vertices, as the operating area's) or a circle
``{centre, radius}``."""


CEILING_MARGIN = 2.0
"""m every flying altitude keeps under an uploaded geofence ceiling: ArduPilot's default
FENCE_MARGIN, the distance it keeps from a fence to avoid a breach."""


class GeofenceConfig(BaseModel):
    """The mission's operating area, an inclusion geofence: the vehicle flies and lands only
    inside ``polygon`` (and below ``max_altitude``), keeping ``margin`` from its edge, and
    never in a no-fly zone of ``exclude``, keeping the same margin from their edges.

    Vertices are ENU ``[x, y]`` metres about home or ``{lat, lon}``, converted like lat/lon
    waypoints (about the vehicle's home on a live link). Sites outside are rejected by the
    Landing Site Manager, search patterns and pattern centres are kept inside, and the
    approach is flown only along a straight leg inside (docs/how-to/write-a-mission.md).
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    polygon: list[Vertex] = Field(
        min_length=3, max_length=MAX_FENCE_VERTICES, description="3 to 1000 vertices of a "
        "simple polygon (no edge crossing another), ENU [x, y] m or {lat, lon}, in order "
        "around the area, not closed (the last joins the first)"
    )
    exclude: list[NoFlyZone] = Field(
        default_factory=list, max_length=MAX_FENCE_ZONES, description="up to 100 no-fly "
        "zones (a building, a crowd, a road, a mast) reaching into the area, each a simple "
        "polygon of 3 to 1000 vertices given as polygon's, or a circle {centre: [x, y] or "
        "{lat, lon}, radius: m}; no site, waypoint, leg or search pattern comes within "
        "margin of one, and upload sends them as exclusion zones"
    )
    margin: float = Field(
        0.0, ge=0, le=MAX_RANGE, description="m kept inside the edge (and out of the no-fly "
        "zones) by sites, waypoints and search patterns, up to 50 km"
    )
    max_altitude: float | None = Field(
        None, gt=0, le=MAX_ALTITUDE, description="m above home no waypoint, cruise, takeoff "
        "or failsafe (clear) altitude may exceed, up to 10 km; unset: no ceiling"
    )
    upload: bool = Field(
        True, description="before takeoff, upload the polygon, the no-fly zones (and "
        "max_altitude) to the autopilot as its own geofence and enable it, so the "
        "autopilot enforces the area too; a refusal fails preflight. false: only this "
        "software keeps to the area"
    )
    restore: bool = Field(
        True, description="after the flight, once the vehicle is down and disarmed, put "
        "back the fence plan and parameters the upload changed on the autopilot. false: the "
        "mission's fence stays in force on the vehicle"
    )


class PerceptionConfig(BaseModel):
    """Which detector feeds the Landing Site Manager, how often, and its settings.

    ``elevation_map``: the simulated depth camera (``camera``, with its ``rangefinder``
    switching SfM/stereo) feeding the elevation-map detector (``elevation_map`` grid,
    ``detection`` thresholds). ``depth_costmap``: the same camera feeding the depth-image
    costmap detector (``depth_costmap``). ``lidar_pca``: the simulated ``lidar`` feeding the
    PCA landing-spot detector (``lidar_pca``). ``scripted``: the sites listed under ``sites``
    in the mission, seen with the ``scripted`` sensor model.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    detector: Literal["elevation_map", "depth_costmap", "lidar_pca", "scripted"] = Field(
        "elevation_map", description="the site source"
    )
    rate: float = Field(
        2.0, ge=0.001, le=100, description="perception updates per second, Hz, 0.001 (one in "
        "17 minutes) .. 100 and at most tick_rate"
    )
    low_altitude_rate: float | None = Field(
        None, ge=0.001, le=100, description="perception updates per second (0.001 .. 100 Hz) "
        "while the range finder "
        "reads less than low_altitude (Hz): a stereo camera close to the ground gives many frames "
        "during the verification hover; default: rate"
    )
    low_altitude: float = Field(
        15.0, gt=0, le=MAX_ALTITUDE, description="range-finder height (m AGL, up to 10 km) "
        "below which low_altitude_rate applies"
    )
    camera: DepthCameraSettings = DepthCameraSettings()
    rangefinder: RangeFinderSettings = RangeFinderSettings()
    elevation_map: ElevationMapSettings = ElevationMapSettings()
    detection: DetectorSettings = DetectorSettings()
    depth_costmap: DepthCostmapSettings = DepthCostmapSettings()
    lidar: LidarSettings = LidarSettings()
    lidar_pca: LidarPcaSettings = Field(
        LidarPcaSettings(max_gap=None), description="the LiDAR PCA detector's settings. In "
        "flight max_gap is off unless the mission sets it: a verification hover's cloud "
        "shows the site's disc but seldom its whole clearance ring, so the coverage rule "
        "would ban sites that are clear (lander detect has it on)"
    )
    scripted: ScriptedSettings = ScriptedSettings()
    descent_flow: DescentFlowSettings = DescentFlowSettings()

    @field_validator("lidar_pca", mode="before")
    @classmethod
    def _coverage_off_in_flight(cls, value: Any) -> Any:
        if isinstance(value, Mapping) and "max_gap" not in value:
            return {**value, "max_gap": None}
        return value


class Mission(BaseModel):
    """A mission file, validated.

    Waypoints are ENU metres ``[x, y, z]`` (z above home) or ``{lat, lon, alt}`` (degrees,
    alt above home), converted with a local tangent plane about ``home`` in lockstep, about
    the home the vehicle reports on a live link (see :class:`VehicleConfig`).
    ``weights.normaliser`` defaults to ``cruise_altitude`` and ``lsm.verification_altitude``
    to ``landing.verification_altitude``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    name: str = Field("", max_length=200, description="title of the flight's report")
    description: str = Field("", max_length=10_000, description="free text")
    vehicle: VehicleConfig = VehicleConfig()
    home: HomeSettings = HomeSettings()
    cruise_altitude: float = Field(
        100.0, ge=1, le=MAX_ALTITUDE, description="m above home, 1 m .. 10 km (a "
        "multicopter's ceiling); also the loss's distance normaliser D by default"
    )
    takeoff_altitude: float | None = Field(
        None, gt=0, le=MAX_ALTITUDE, description="m above home, up to 10 km; default: the "
        "first waypoint's altitude"
    )
    waypoints: list[Waypoint] = Field(
        min_length=1, max_length=MAX_WAYPOINTS, description="1 to 1000 waypoints, ENU "
        "[x, y, z] metres or {lat, lon, alt}, each within 50 km of home and 10 km above it"
    )
    weights: LossWeights = LossWeights()
    lsm: LsmSettings = LsmSettings()
    landing: LandingSettings = LandingSettings()
    world: TerrainSettings = Field(default_factory=_flat_world)
    sitl: SitlSettings = SitlSettings()
    perception: PerceptionConfig = PerceptionConfig()
    sites: list[ScriptedSite] = Field(
        default_factory=list, max_length=MAX_SITES,
        description="sites of the scripted source, at most 10,000",
    )
    seed: int = Field(
        0, ge=0, le=MAX_SEED, description="seeds terrain, sensor noise, wind, pattern "
        "centres: 0 .. 2**32-1 (numpy's generators take non-negative integers)"
    )
    tick_rate: float = Field(
        10.0, ge=1, le=100, description="tree ticks per second, Hz, 1 .. 100: the tree must "
        "look at the vehicle at least once a second (GUIDED targets time out in 3 s), and "
        "autopilots stream their state at up to 50 Hz, so ticking faster decides again on "
        "the same state; a lockstep step is 1 / tick_rate of simulated time"
    )
    time_limit: float = Field(
        1800.0, gt=0, le=MAX_TIME_LIMIT, description="s of mission time before aborting, up "
        "to 4 hours (longer than any multicopter battery lasts)"
    )
    geofence: GeofenceConfig | None = Field(
        None, description="the operating area (inclusion geofence) the mission flies and "
        "lands in; unset: anywhere"
    )
    tree: str | None = Field(
        None, min_length=1, max_length=4096, description="BehaviorTree.CPP v4 XML tree file "
        "to fly instead of the built-in landing tree, relative to the mission file "
        "(docs/trees.md); checked against the node registry and this mission when loaded"
    )

    _source: dict[str, Any] = PrivateAttr(default_factory=dict)

    @model_validator(mode="wrap")
    @classmethod
    def _derived_defaults(cls, data: Any, handler: Any) -> Mission:
        source = data
        if isinstance(data, Mapping):
            data = _with_derived_defaults(data)
        mission = handler(data)
        if isinstance(source, Mapping):
            mission._source = copy.deepcopy(dict(source))
        return mission

    @model_validator(mode="after")
    def _rates(self) -> Mission:
        for name in ("rate", "low_altitude_rate"):
            rate = getattr(self.perception, name)
            if rate is not None and rate > self.tick_rate:
                raise ValueError(
                    f"perception.{name}: {rate} Hz is faster than tick_rate "
                    f"({self.tick_rate} Hz); perception runs at most once per tick"
                )
        return self

    @model_validator(mode="after")
    def _geometry(self) -> Mission:
        self.check_geometry()
        return self

    def check_geometry(
        self, home: tuple[float, float] | None = None, project: Projection | None = None
    ) -> None:
        """Check the mission's geometry about ``home`` (lat, lon; default: the file's),
        converted with ``project`` (see :meth:`waypoints_enu`): lat/lon waypoints within
        range, the route on an elevation model, the geofence a simple polygon with an area
        and home, the waypoints and the legs between them inside it and out of its no-fly
        zones (each a simple polygon reaching into it), every altitude under its ceiling.
        The validators check the file about its own home; a flight converts about the home
        it flies by, and :meth:`plan` checks again about that one (ENU waypoints and
        vertices move with the home, lat/lon ones do not).

        Raises:
            ValueError: the first rule broken, naming the field and the coordinates.
        """
        waypoints = self.waypoints_enu(home, project)
        if any(isinstance(wp, GeoWaypoint) for wp in self.waypoints):
            for i, (x, y, _) in enumerate(waypoints):
                distance = math.hypot(x, y)
                if distance > MAX_RANGE:
                    raise ValueError(
                        f"waypoints.{i}: {distance:.0f} m from home, more than the "
                        f"{MAX_RANGE:.0f} m a multicopter flies"
                    )
        if self.world.kind == "file":  # no ground off an elevation model: stay on it
            from sitl.terrain.files import check_route

            check_route(self.world, waypoints, self.landing.search_rectangle,
                        self.landing.pattern_center_radius)
        area = self.operating_area(home, project)
        if area is not None:
            self._check_geofence(area, waypoints)

    def _check_geofence(self, area: OperatingArea,
                        waypoints: list[tuple[float, float, float]]) -> None:
        fence = self.geofence
        assert fence is not None
        _check_polygon("geofence.polygon", area.vertices)
        for k, zone in enumerate(area.exclusions):
            if not isinstance(zone, NoFlyCircle):
                _check_polygon(f"geofence.exclude.{k}", zone)
            if not area.overlaps(zone):
                raise ValueError(f"geofence.exclude.{k}: the no-fly zone lies outside "
                                 "geofence.polygon (no part of it is in the area)")
        where = (f"at least {fence.margin:g} m inside the geofence" if fence.margin
                 else "inside the geofence")
        in_zone = f" (or within its {fence.margin:g} m margin)" if fence.margin else ""
        if not area.contains_point(0.0, 0.0):
            k = int(area.zone_of((0.0, 0.0))[0])
            if k >= 0:
                raise ValueError(f"geofence.exclude.{k}: home (0, 0) is in this no-fly "
                                 f"zone{in_zone}")
            raise ValueError(f"geofence.polygon: home (0, 0) is not {where}")
        xy = np.array([wp[:2] for wp in waypoints])
        inside = area.contains(xy)
        for i in np.flatnonzero(~inside).tolist():
            x, y, _ = waypoints[i]
            k = int(area.zone_of(xy[i])[0])
            if k >= 0:
                raise ValueError(f"waypoints.{i}: ({x:.1f}, {y:.1f}) is in the no-fly zone "
                                 f"geofence.exclude.{k}{in_zone}")
            raise ValueError(f"waypoints.{i}: ({x:.1f}, {y:.1f}) is not {where}")
        # The legs too: in a non-convex area two waypoints inside may have the edge between.
        route = [(0.0, 0.0), *(wp[:2] for wp in waypoints)]
        for i in range(len(waypoints)):
            if not area.leg_inside(route[i], route[i + 1]):
                came = "home" if i == 0 else f"waypoint {i - 1}"
                k = area.leg_zone(route[i], route[i + 1])
                if k is not None:
                    near = (f" (or comes within its {fence.margin:g} m margin)"
                            if fence.margin else "")
                    raise ValueError(f"waypoints.{i}: the straight leg from {came} crosses "
                                     f"the no-fly zone geofence.exclude.{k}{near}; add a "
                                     "waypoint to go round it")
                raise ValueError(f"waypoints.{i}: the straight leg from {came} leaves the "
                                 f"geofence (or comes within its margin of the edge); add a "
                                 "waypoint at the corner")
        ceiling = fence.max_altitude
        if ceiling is None:
            return
        # The autopilot breaches at its ceiling (ArduPilot: altitude >= FENCE_ALT_MAX), so
        # a climb's overshoot to an altitude at the ceiling would meet its breach action:
        # with the fence uploaded, altitudes stay FENCE_MARGIN under it.
        room = CEILING_MARGIN if fence.upload else 0.0
        under = (f"not {room:g} m under geofence.max_altitude ({ceiling:g} m), which the "
                 "autopilot enforces (geofence.upload): a climb's overshoot would breach it"
                 if room else f"above geofence.max_altitude ({ceiling:g} m)")
        for i, (_, _, z) in enumerate(waypoints):
            if z > ceiling - room:
                raise ValueError(f"waypoints.{i}: altitude {z:g} m is {under}")
        for name, value in (("cruise_altitude", self.cruise_altitude),
                            ("takeoff_altitude", self.takeoff_altitude),
                            ("landing.failsafe_altitude", self.landing.failsafe_altitude)):
            if value is not None and value > ceiling - room:
                what = " (the cap of the clear altitude)" if name.startswith("landing") else ""
                raise ValueError(f"{name}: {value:g} m{what} is {under}")

    def operating_area(
        self, home: tuple[float, float] | None = None, project: Projection | None = None
    ) -> OperatingArea | None:
        """The geofence as an :class:`lsm.area.OperatingArea` in ENU metres about home
        (lat/lon vertices converted as :meth:`waypoints_enu` converts waypoints), or None."""
        fence = self.geofence
        if fence is None:
            return None
        lat0, lon0 = (self.home.lat, self.home.lon) if home is None else home
        project = project or geodetic_to_enu

        def point(v: Any) -> tuple[float, float]:
            if isinstance(v, GeoVertex):
                x, y = project(v.lat, v.lon, lat0, lon0)
                return float(x), float(y)
            return float(v[0]), float(v[1])

        def zone(z: Any) -> tuple[tuple[float, float], ...] | NoFlyCircle:
            if isinstance(z, NoFlyCircleZone):
                return NoFlyCircle(*point(z.centre), float(z.radius))
            return tuple(point(v) for v in z)

        return OperatingArea(tuple(point(v) for v in fence.polygon), fence.margin,
                             fence.max_altitude, tuple(zone(z) for z in fence.exclude))

    @property
    def has_home(self) -> bool:
        """True when the mission file gives a ``home`` (else it is the default)."""
        return "home" in self.source_data()

    @property
    def home_source(self) -> str | None:
        """Where the mission's home comes from: ``"mission file"`` (its ``home``),
        ``"elevation model"`` (a model with a coordinate system, at the world's home, for a
        file that gives no home) or None (the default home, which places nothing)."""
        data = self.source_data()
        if "home" in data:
            return "mission file"
        sitl = data.get("sitl")
        if getattr(self.world, "kind", None) != "file" or (
                isinstance(sitl, Mapping) and "home" in sitl):
            return None
        from sitl.terrain.files import georeference

        return "elevation model" if georeference(self.world) is not None else None

    def waypoints_enu(
        self, home: tuple[float, float] | None = None, project: Projection | None = None
    ) -> list[tuple[float, float, float]]:
        """The waypoints as ENU metres about home: lat/lon ones are converted about ``home``
        (lat, lon degrees; default: the file's ``home``) with ``project(lat, lon, lat0,
        lon0) -> (east, north)`` (default: the WGS-84 tangent plane, :func:`geodetic_to_enu`;
        a live flight passes the autopilot's own projection)."""
        lat0, lon0 = (self.home.lat, self.home.lon) if home is None else home
        project = project or geodetic_to_enu
        out = []
        for wp in self.waypoints:
            if isinstance(wp, GeoWaypoint):
                x, y = project(wp.lat, wp.lon, lat0, lon0)
                z = self.cruise_altitude if wp.alt is None else wp.alt
                out.append((x, y, float(z)))
            else:
                out.append(tuple(float(v) for v in wp))
        return out

    def plan(
        self, home: tuple[float, float] | None = None, project: Projection | None = None
    ) -> MissionPlan:
        """The :class:`behaviors.settings.MissionPlan` the tree is built from; lat/lon
        waypoints and geofence vertices are converted about ``home`` (see
        :meth:`waypoints_enu`).

        Raises:
            ValueError: converted about another home or with another projection than the
                file was checked with, the plan breaks a rule of :meth:`check_geometry`
                (a lat/lon fence stays where it is on the Earth, ENU waypoints move with
                the home, and the other way round).
        """
        if home is not None or project is not None:
            self.check_geometry(home, project)
        return MissionPlan(
            waypoints=self.waypoints_enu(home, project),
            takeoff_altitude=self.takeoff_altitude,
            cruise_altitude=self.cruise_altitude,
            landing=self.landing,
            geofence=self.operating_area(home, project),
            geofence_upload=self.geofence is not None and self.geofence.upload,
        )

    def source_data(self) -> dict[str, Any]:
        """The mission as the user wrote it (before derived defaults), a deep copy."""
        if self._source:
            return copy.deepcopy(self._source)
        return self.model_dump(exclude_unset=True)


def _check_polygon(name: str, corners: Sequence[tuple[float, float]]) -> None:
    """Raise ``name: ...`` when the polygon ``corners`` (ENU m) encloses no area or is not
    simple (the autopilots reject such fences, and inside/outside means nothing for them)."""
    x, y = np.asarray(corners).T
    if abs(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y)) / 2 < 1.0 and (
            len(corners) == 3 or self_intersection(corners) is None):
        raise ValueError(f"{name}: encloses no area (under 1 m^2)")
    crossing = self_intersection(corners)
    if crossing is not None:
        i, j = crossing
        raise ValueError(f"{name}: not a simple polygon: edge {i} "
                         f"(vertices {i}-{(i + 1) % len(corners)}) meets edge {j} "
                         f"(vertices {j}-{(j + 1) % len(corners)})")


def _positive(value: Any, model: type[BaseModel] | None = None, name: str = ""
              ) -> float | None:
    """``value`` as a positive finite float that ``model.name`` accepts, or None (left for
    validation to report where the user wrote it, not where it would be copied to)."""
    number = _positive_number(value)
    if number is None or model is None:
        return number
    try:
        _field_adapter(model, name).validate_python(number)
    except ValidationError:
        return None
    return number


@functools.cache
def _field_adapter(model: type[BaseModel], name: str) -> TypeAdapter:
    info = model.model_fields[name]
    return TypeAdapter(Annotated[info.annotation, info])


def _positive_number(value: Any) -> float | None:
    """``value`` as a positive finite float, or None (left for validation to report)."""
    if isinstance(value, bool):
        return None
    try:
        number = float(value)
    except (TypeError, ValueError):
        return None
    return number if math.isfinite(number) and number > 0 else None


def _valid(model: type[BaseModel], value: Any) -> bool:
    try:
        model.model_validate(value)
    except ValidationError:
        return False
    return True


def _with_derived_defaults(data: Mapping[str, Any]) -> dict[str, Any]:
    """Fill the defaults that follow other fields, where the user left them out."""
    data = dict(data)
    cruise = _positive(data.get("cruise_altitude", 100.0), LossWeights, "normaliser")
    weights = data.get("weights")
    if cruise is not None and (weights is None or isinstance(weights, Mapping)):
        weights = dict(weights or {})
        weights.setdefault("normaliser", cruise)
        data["weights"] = weights
    landing = data.get("landing")
    lsm = data.get("lsm")
    if isinstance(landing, LandingSettings):
        ver_alt: Any = landing.verification_altitude
    elif isinstance(landing, Mapping):
        ver_alt = landing.get("verification_altitude", LandingSettings().verification_altitude)
    else:
        ver_alt = LandingSettings().verification_altitude
    ver_alt = _positive(ver_alt, LsmSettings, "verification_altitude")
    if ver_alt is not None and (lsm is None or isinstance(lsm, Mapping)):
        lsm = dict(lsm or {})
        lsm.setdefault("verification_altitude", ver_alt)
        data["lsm"] = lsm
    data = _home_on_elevation_model(data)
    home = data.get("home")
    sitl = data.get("sitl")
    if (isinstance(home, Mapping) and (sitl is None or isinstance(sitl, Mapping))
            and _valid(HomeSettings, home)):
        sitl = dict(sitl or {})  # the simulator's home is the mission's home
        sitl.setdefault("home", dict(home))
        data["sitl"] = sitl
    return data


def _home_on_elevation_model(data: dict[str, Any]) -> dict[str, Any]:
    """A mission over an elevation model with a coordinate system flies where the model is
    on the Earth: the mission's ``home`` (lat, lon) places home on the model unless
    ``world.home`` says where; without a ``home``, the mission's home is the model's
    position (and ground height) at the world's home. So the GPS the simulator reports and
    lat/lon waypoints agree with the ground under the vehicle."""
    world = data.get("world")
    if not (isinstance(world, Mapping) and world.get("kind") == "file"):
        return data
    try:
        settings = TypeAdapter(TerrainSettings).validate_python(world)
    except (ValidationError, ValueError):
        return data  # the mission's own validation names what is wrong
    from sitl.terrain.files import georeference

    home = data.get("home")
    if settings.home is None and isinstance(home, Mapping):
        if not _valid(HomeSettings, home):
            return data
        placed = {**world, "home": {"lat": home.get("lat", HomeSettings().lat),
                                    "lon": home.get("lon", HomeSettings().lon)}}
        try:
            if georeference(settings) is None:
                return data  # a model without a coordinate system: home at its centre
            TypeAdapter(TerrainSettings).validate_python(placed)
        except (ValidationError, ValueError) as exc:
            said = exc.errors()[0]["msg"] if isinstance(exc, ValidationError) else str(exc)
            if "no place in" in said:
                raise ValueError(one_line(said.removeprefix("Value error, "))) from None
            where = "the window of " if settings.window is not None else ""
            raise ValueError(
                f"home: lat {home.get('lat')}, lon {home.get('lon')} is off {where}the "
                f"elevation model {settings.path.name}, which has a coordinate system: move "
                "home onto it, or give world.home ([x, y] m from its south-west corner)"
            ) from None
        return {**data, "world": placed}
    sitl = data.get("sitl")
    if home is None and not (isinstance(sitl, Mapping) and "home" in sitl):
        at = georeference(settings)
        if at is not None:
            lat, lon, ground = at
            return {**data, "home": {"lat": lat, "lon": lon,
                                     "alt": min(max(ground, -500.0), 9000.0)}}
    return data


def geodetic_to_enu(lat: float, lon: float, lat0: float, lon0: float) -> tuple[float, float]:
    """East and north metres of (lat, lon) in the tangent plane at (lat0, lon0), degrees in.

    Both points are taken on the WGS-84 ellipsoid at zero height; the result is exact ENU
    (via ECEF) projected on the horizontal plane.
    """

    def ecef(lat_d: float, lon_d: float) -> tuple[float, float, float]:
        phi, lam = math.radians(lat_d), math.radians(lon_d)
        n = _WGS84_A / math.sqrt(1 - _WGS84_E2 * math.sin(phi) ** 2)
        return (
            n * math.cos(phi) * math.cos(lam),
            n * math.cos(phi) * math.sin(lam),
            n * (1 - _WGS84_E2) * math.sin(phi),
        )

    x, y, z = ecef(lat, lon)
    x0, y0, z0 = ecef(lat0, lon0)
    dx, dy, dz = x - x0, y - y0, z - z0
    phi0, lam0 = math.radians(lat0), math.radians(lon0)
    east = -math.sin(lam0) * dx + math.cos(lam0) * dy
    north = (
        -math.sin(phi0) * math.cos(lam0) * dx
        - math.sin(phi0) * math.sin(lam0) * dy
        + math.cos(phi0) * dz
    )
    return east, north


# --------------------------------------------------------------------------------------
# Loading with file:line:field messages


class MissionFileError(UserError):
    """A mission file with problems; ``problems`` holds one message per problem."""

    def __init__(self, problems: Sequence[str]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(self.problems))


MAX_MISSION_BYTES = 10_000_000
"""A mission file is at most 10 MB: 1000 waypoints and 10,000 sites take well under 1 MB."""


def load_mission(path: str | os.PathLike[str]) -> Mission:
    """Read and validate a mission file.

    Raises:
        MissionFileError: (a :class:`~autonomy.errors.UserError`) unreadable file, YAML
            syntax errors, duplicate keys, and every schema problem, one message each as
            ``FILE:LINE: FIELD: REASON``.
    """
    path = Path(path)
    try:
        info = path.stat()
        if not stat.S_ISREG(info.st_mode):
            what = "a directory" if stat.S_ISDIR(info.st_mode) else "not a regular file"
            raise MissionFileError([f"{path}: cannot read mission file: {what}"])
        if info.st_size > MAX_MISSION_BYTES:
            raise MissionFileError([f"{path}: cannot read mission file: {info.st_size:,} "
                                    f"bytes, more than {MAX_MISSION_BYTES:,}"])
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        if isinstance(exc, MissionFileError):
            raise
        if isinstance(exc, UnicodeDecodeError):
            reason = f"not UTF-8 text (byte {exc.start})"
        else:
            reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise MissionFileError([f"{path}: cannot read mission file: {reason}"]) from None
    mission = parse_mission(text, str(path), base_dir=path.parent)
    if not mission.name:  # reports are titled with the file's name then
        mission = apply_overrides(mission, {"name": path.stem[:200]})
    return mission


def parse_mission(text: str, name: str = "<mission>", base_dir: Path | None = None) -> Mission:
    """Validate mission YAML ``text``; ``name`` is used in the messages (see load_mission).

    A relative ``world.path`` (elevation file) is taken relative to ``base_dir`` (the mission
    file's directory) when given.
    """
    loader = YamlLoader(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else 1
        what = one_line(exc.problem or exc.context or "malformed YAML")
        lines = text.splitlines()
        line_text = lines[mark.line][: mark.column + 1] if (
            mark is not None and mark.line < len(lines)) else ""
        if "tab" not in what and "\t" in line_text:
            what += " (a tab: YAML indents with spaces only)"
        raise MissionFileError([f"{name}:{line}: YAML syntax error: {what}"]) from None
    except yaml.YAMLError as exc:
        raise MissionFileError([f"{name}:1: YAML error: {one_line(str(exc))}"]) from None
    except RecursionError:
        raise MissionFileError([f"{name}:1: YAML error: nested too deeply"]) from None
    finally:
        loader.dispose()
    if node is None:
        raise MissionFileError([f"{name}:1: empty mission file"])
    if not isinstance(node, yaml.MappingNode) or not isinstance(data, dict):
        line = node.start_mark.line + 1
        raise MissionFileError([f"{name}:{line}: a mission file is a mapping of sections"])
    problems = _duplicate_keys(node, name)
    world = data.get("world")
    if (base_dir is not None and isinstance(world, dict) and world.get("kind") == "file"
            and isinstance(world.get("path"), str) and not Path(world["path"]).is_absolute()):
        data["world"] = {**world, "path": str(base_dir / world["path"])}
    tree = data.get("tree")
    if base_dir is not None and isinstance(tree, str) and tree and not Path(tree).is_absolute():
        data["tree"] = str(base_dir / tree)
    mission, errors = _validate(data)
    problems += [_locate(err, node, name) for err in errors]
    if mission is not None and mission.tree is not None:
        problems += _tree_problems(mission, node, name)
    if problems or mission is None:
        raise MissionFileError(sorted(dict.fromkeys(problems), key=_line_of))
    return mission


def _tree_problems(mission: Mission, root: yaml.Node, name: str) -> list[str]:
    """The problems of the mission's tree file, each at its own file and line."""
    from behaviors.loader import TreeFileError, check_tree, read_tree
    from behaviors.registry import mission_settings

    try:
        readable = Path(mission.tree).is_file()
    except (OSError, ValueError):  # e.g. a NUL in the name
        readable = False
    if not readable:
        reason = f"cannot read tree file {mission.tree!r}: no such file"
        return [_locate({"type": "value_error", "loc": ("tree",), "msg": reason}, root, name)]
    try:
        document = read_tree(mission.tree)
    except TreeFileError as exc:
        return exc.problems
    from autonomy.runner.services import service_names

    return check_tree(document, mission_settings(mission.plan(), mission.lsm.match_radius),
                      service_names(mission))


def _validate(data: Any) -> tuple[Mission | None, list[dict[str, Any]]]:
    """The mission, or None and pydantic's error dicts (plus numbers written as true/false,
    which pydantic would take as 1 and 0)."""
    try:
        mission = Mission.model_validate(data)
    except ValidationError as exc:
        return None, list(exc.errors())
    except RecursionError:
        return None, [{"type": "value_error", "loc": (), "msg": "nested too deeply"}]
    errors = [
        {"type": "bool_number", "loc": loc, "input": raw,
         "msg": "must be a number, not true or false"}
        for loc, raw in _numbers_given_as_bools(mission, data, ())
    ]
    return (None, errors) if errors else (mission, [])


def _numbers_given_as_bools(value: Any, raw: Any, loc: tuple) -> Iterator[tuple[tuple, Any]]:
    """Locations where the file wrote true/false and the model holds a number."""
    if isinstance(raw, bool):
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            yield loc, raw
        return
    if isinstance(value, BaseModel) and isinstance(raw, Mapping):
        for name in type(value).model_fields:
            if name in raw:
                yield from _numbers_given_as_bools(getattr(value, name), raw[name], (*loc, name))
    elif (isinstance(value, (list, tuple)) and isinstance(raw, (list, tuple))
          and len(value) == len(raw)):
        for i, (v, r) in enumerate(zip(value, raw, strict=True)):
            yield from _numbers_given_as_bools(v, r, (*loc, i))
    elif isinstance(value, Mapping) and isinstance(raw, Mapping):
        for key, r in raw.items():
            if key in value:
                yield from _numbers_given_as_bools(value[key], r, (*loc, key))


def _duplicate_keys(root: yaml.Node, name: str) -> list[str]:
    problems = []
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    visited: set[int] = set()  # anchors and aliases share nodes: visit each once
    while stack:
        node, prefix = stack.pop()
        if id(node) in visited:
            continue
        visited.add(id(node))
        if isinstance(node, yaml.MappingNode):
            seen: set[str] = set()
            for key, value in node.value:
                label = str(key.value)
                field = f"{prefix}{label}"
                if label in seen:
                    problems.append(f"{name}:{key.start_mark.line + 1}: {field}: duplicate key")
                seen.add(label)
                stack.append((value, field + "."))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((v, f"{prefix}{i}.") for i, v in enumerate(node.value))
    return problems


def _line_of(message: str) -> int:
    match = re.search(r":(\d+): ", message)
    return int(match.group(1)) if match else 0




def _yaml_children(node: Any) -> tuple[str, Any]:
    if isinstance(node, yaml.MappingNode):
        return "map", {str(k.value): (k, v) for k, v in node.value}
    if isinstance(node, yaml.SequenceNode):
        return "seq", node.value
    return "scalar", None


def _data_children(node: Any) -> tuple[str, Any]:
    if isinstance(node, Mapping):
        return "map", {str(k): (None, v) for k, v in node.items()}
    if isinstance(node, (list, tuple)):
        return "seq", list(node)
    return "scalar", None


def describe_error(err: Mapping[str, Any], data: Any, model: Any = None) -> tuple[str, str]:
    """(field, reason) of one pydantic error of validating ``data`` against ``model`` (a
    settings model or a union of them; default: the mission): the dotted field as the user
    wrote it and the reason in the project's words, with the field's bounds and why."""
    field, reason, _ = _describe(err, data, _data_children, model)
    return field, reason


def _describe(err: Mapping[str, Any], root: Any, children: Any, model: Any = None
              ) -> tuple[str, str, Any]:
    """(field, reason, node) of one pydantic error: the dotted field as the user wrote it
    (union tags and model names pydantic adds to locations left out; never empty), the
    reason in one line, and the node (YAML or data) it points at."""
    node = mark = root
    parts: list[str] = []
    loc: list[Any] = list(err.get("loc", ()))
    msg = str(err.get("msg", "invalid"))
    for prefix in ("Value error, ", "Assertion failed, "):
        msg = msg.removeprefix(prefix)
    # Model-level checks name the field they are about first ("search_rectangle: ..."):
    # point at that field.
    named = re.match(r"([A-Za-z_][\w.]*): ", msg)
    if named and err.get("type") == "value_error":
        loc += [int(p) if p.isdigit() else p for p in named.group(1).split(".")]
        msg = msg[named.end():]
    for i, item in enumerate(loc):
        last = i == len(loc) - 1
        kind, kids = children(node)
        if kind == "map" and (not isinstance(item, int) or str(item) in kids):
            match = kids.get(str(item))
            if match is not None:
                parts.append(str(item))
                key, node = match
                forbidden = err.get("type") == "extra_forbidden" and last
                mark = key if forbidden and key is not None else node
                continue
            if last:  # a missing field: name it, point at its mapping
                parts.append(str(item))
            # otherwise a union tag or model name pydantic adds to locations: skip it
        elif kind == "seq" and isinstance(item, int):
            if 0 <= item < len(kids):
                parts.append(str(item))
                node = mark = kids[item]
                continue
            parts.append(str(item))
        elif isinstance(item, int) and kind == "scalar":
            parts.append(str(item))  # an item of a scalar that should be a list
    field = ".".join(_shown_key(p) for p in parts) or ("(mission)" if model is None
                                                        else "(settings)")
    value = err.get("input")
    kind = str(err.get("type"))
    msg = _REASONS[kind](err.get("ctx") or {}) if kind in _REASONS else msg
    roots = [Mission] if model is None else list(_models_in(model))
    if kind == "extra_forbidden" and loc:
        msg += _did_you_mean(str(loc[-1]), loc[:-1], roots)
    if kind == "int_parsing_size":  # pydantic gives no bound: the field has it
        high = _upper_bound(_field_info(loc, roots))
        if high is not None:
            msg, kind = f"must be <= {high}", "less_than_equal"
    if kind not in ("missing", "value_error", "extra_forbidden") and isinstance(
        value, (int, float, str, bool)
    ):
        shown = ("true" if value else "false") if isinstance(value, bool) else repr(value)
        msg = f"{msg} (got {shown if len(shown) <= 60 else shown[:57] + '...'})"
    if kind in _BOUND_ERRORS:
        about = _field_description(loc, roots)
        if about:
            msg = f"{msg}; {about}"
    return field, one_line(msg), mark


_REASONS: dict[str, Callable[[Mapping[str, Any]], str]] = {
    "greater_than": lambda c: f"must be > {c.get('gt')}",
    "greater_than_equal": lambda c: f"must be >= {c.get('ge')}",
    "less_than": lambda c: f"must be < {c.get('lt')}",
    "less_than_equal": lambda c: f"must be <= {c.get('le')}",
    "finite_number": lambda c: "must be a finite number",
    "int_parsing": lambda c: "must be an integer",
    "int_type": lambda c: "must be an integer",
    "int_from_float": lambda c: "must be a whole number",
    "int_parsing_size": lambda c: "a number too large",
    "float_parsing": lambda c: "must be a number",
    "float_type": lambda c: "must be a number",
    "bool_parsing": lambda c: "must be true or false",
    "bool_type": lambda c: "must be true or false",
    "string_type": lambda c: "must be text",
    "list_type": lambda c: "must be a list",
    "tuple_type": lambda c: "must be a list",
    "dict_type": lambda c: "must be a mapping of settings",
    "model_type": lambda c: "must be a mapping of settings",
    "model_attributes_type": lambda c: "must be a mapping of settings",
    "missing": lambda c: "required",
    "extra_forbidden": lambda c: "unknown setting",
    "literal_error": lambda c: f"must be {c.get('expected')}",
    "union_tag_invalid": lambda c: f"{c.get('discriminator', 'kind')} must be "
                                   f"{c.get('expected_tags')}, not {c.get('tag')!r}",
    "union_tag_not_found": lambda c: f"needs {c.get('discriminator', 'kind')}",
    "too_long": lambda c: f"at most {c.get('max_length')} "
                          f"{'characters' if c.get('field_type') == 'Value' else 'items'}",
    "too_short": lambda c: f"at least {c.get('min_length')} "
                           f"{'characters' if c.get('field_type') == 'Value' else 'items'}",
    "string_too_long": lambda c: f"at most {c.get('max_length')} characters",
    "string_too_short": lambda c: f"at least {c.get('min_length')} characters",
}
"""Reasons in the project's words for pydantic's error types (the rest keep pydantic's)."""

_BOUND_ERRORS = frozenset({
    "greater_than", "greater_than_equal", "less_than", "less_than_equal", "too_long",
    "too_short", "string_too_long", "string_too_short",
})


def _did_you_mean(key: str, parent: Sequence[Any], roots: Sequence[type[BaseModel]]) -> str:
    """``; did you mean NAME?`` when ``key`` looks like a typo of a setting of the section
    at ``parent`` (the settings of the section's kind, for a section with kinds)."""
    models: list[type[BaseModel]] = list(roots)
    for item in parent:
        if not isinstance(item, str):
            continue
        owner = next((m for m in models if item in m.model_fields), None)
        if owner is not None:
            models = list(_models_in(owner.model_fields[item].annotation))
            continue
        tagged = [m for m in models if item in typing.get_args(
            getattr(m.model_fields.get("kind"), "annotation", None))]
        models = tagged or models  # the kind pydantic adds to locations in a tagged union
    return did_you_mean(key, {info.alias or name for m in models
                              for name, info in m.model_fields.items()})


def _field_description(loc: Sequence[Any], roots: Sequence[type[BaseModel]]) -> str | None:
    """The schema's description of the innermost field along ``loc`` (it says the field's
    unit, bounds and why), or None."""
    info = _field_info(loc, roots)
    return None if info is None else info.description


def _field_info(loc: Sequence[Any], roots: Sequence[type[BaseModel]]) -> Any:
    """The pydantic FieldInfo of the innermost field along ``loc`` from ``roots``, or None."""
    models: list[type[BaseModel]] = list(roots)
    found = None
    for item in loc:
        if not isinstance(item, str):
            continue
        owner = next((m for m in models if item in m.model_fields), None)
        if owner is None:
            continue  # a union tag or model name pydantic adds to locations
        found = owner.model_fields[item]
        models = list(_models_in(found.annotation))
    return found


def _upper_bound(info: Any) -> Any:
    for constraint in getattr(info, "metadata", ()):
        for name in ("le", "lt"):
            if getattr(constraint, name, None) is not None:
                return getattr(constraint, name)
    return None


def _models_in(annotation: Any) -> Iterator[type[BaseModel]]:
    """The pydantic models an annotation holds (through unions, lists, Annotated...)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        yield annotation
        return
    for arg in typing.get_args(annotation):
        yield from _models_in(arg)


def _shown_key(key: str) -> str:
    """A key as it can be shown in a dotted field name: quoted when it is not plain text."""
    plain = key and key.isprintable() and not any(c in key for c in ".: '\"") and (
        key.strip() == key)
    return key if plain else repr(key)


def _locate(err: Mapping[str, Any], root: yaml.Node, name: str) -> str:
    """One message for one pydantic error, at the YAML node its location points to."""
    field, msg, mark = _describe(err, root, _yaml_children)
    return f"{name}:{mark.start_mark.line + 1}: {field}: {msg}"


# --------------------------------------------------------------------------------------
# Overrides


def apply_overrides(mission: Mission, overrides: Mapping[str, Any]) -> Mission:
    """A copy of ``mission`` with dotted keys set (``{"landing.verification_altitude": 5}``).

    Keys follow the mission file's structure; list items are addressed by index
    (``"sites.0.verifies"``). Derived defaults (e.g. ``weights.normaliser`` from
    ``cruise_altitude``) follow the new values unless the mission set them explicitly.

    Raises:
        UserError: a key the schema does not have, or a value it rejects: one line, each
            problem as ``override KEY: REASON`` (``override KEY: FIELD: REASON`` when the
            value makes another field wrong).
    """
    data = mission.source_data()
    for key, value in overrides.items():
        _set_dotted(data, key, value)
    validated, errors = _validate(data)
    if validated is not None:
        return validated
    problems = []
    for err in errors:
        field, msg, _ = _describe(err, data, _data_children)
        key = next(
            (k for k in overrides if field == k or field.startswith(k + ".")
             or k.startswith(field + ".")),
            None,
        )
        if key is None:
            keys = ", ".join(overrides) or "none"
            problems.append(f"{field}: {msg} (with the overrides: {keys})")
        elif field == key or key.startswith(field + "."):
            problems.append(f"override {key}: {msg}")
        else:
            problems.append(f"override {key}: {field}: {msg}")
    raise UserError("; ".join(dict.fromkeys(problems)))


def _set_dotted(data: dict[str, Any], key: str, value: Any) -> None:
    parts = key.split(".")
    if not key or any(not p for p in parts):
        raise UserError(f"override {key!r}: not a dotted setting name")
    node: Any = data
    for i, part in enumerate(parts):
        last = i == len(parts) - 1
        if isinstance(node, list):
            if not part.isdigit() or int(part) >= len(node):
                raise UserError(f"override {key}: unknown setting (no item {part})")
            index: Any = int(part)
        elif isinstance(node, dict):
            index = part
        else:
            raise UserError(f"override {key}: unknown setting")
        if last:
            node[index] = value
            return
        child = node[index] if (isinstance(node, list) or index in node) else {}
        if isinstance(child, BaseModel):
            child = child.model_dump()
        elif isinstance(child, Mapping):
            child = dict(child)
        elif isinstance(child, tuple):
            child = list(child)
        node[index] = child
        node = child
