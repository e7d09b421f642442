"""The mission file: its schema, loading with file:line:field errors, and overrides.

A mission file is YAML. Its schema (:class:`Mission`, pydantic v2, unknown keys forbidden)
composes the settings models each package owns: :class:`lsm.settings.LossWeights` and
:class:`lsm.settings.LsmSettings`, :class:`behaviors.settings.LandingSettings`, the terrain
settings of :mod:`sitl.terrain` and the simulator's ``SitlSettings``.

:func:`load_mission` reports every problem of a file at once, one message per problem, each
naming the file, the line and the field (``missions/x.yaml:12: landing.acceptance_radius:
Input should be greater than 0 (got -1)``). :func:`apply_overrides` sets dotted keys on a
mission (campaigns vary settings this way) and re-validates it.
"""

from __future__ import annotations

import copy
import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Annotated, Any, Literal

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
    model_validator,
)

from autonomy.errors import UserError
from autonomy.perception.scripted import ScriptedSettings, ScriptedSite
from autonomy.vehicle.connection import signing_key_from_text
from autonomy.vehicle.settings import VehicleLinkSettings
from behaviors.settings import LandingSettings, MissionPlan
from lsd.depth_costmap_settings import DepthCostmapSettings
from lsd.elevation_settings import DetectorSettings, ElevationMapSettings
from lsd.lidar_pca_settings import LidarPcaSettings
from lsm.settings import LossWeights, LsmSettings
from sitl import SitlSettings
from sitl.copter import HomeSettings
from sitl.sensors import DepthCameraSettings, RangeFinderSettings
from sitl.sensors.lidar import LidarSettings
from sitl.terrain import TerrainSettings

# WGS-84, for the local tangent plane about home.
_WGS84_A = 6378137.0
_WGS84_E2 = 6.69437999014e-3


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
        description="sim:// (embedded SITL, lockstep) or a pymavlink URL (udp:, tcp:, serial)",
    )
    autopilot: Literal["ardupilot", "px4"] = Field(
        "ardupilot", description="personality of the embedded SITL (sim:// only)"
    )
    signing_key: str | None = Field(
        None, description="MAVLink 2 signing key: 64 hex digits or a passphrase"
    )
    signing_key_env: str | None = Field(
        None, description="name of an environment variable holding the signing key"
    )
    link: VehicleLinkSettings = VehicleLinkSettings()
    home_from: HomeSource | None = Field(
        None, description="live flights whose file home and vehicle home disagree: fly by "
        "the 'vehicle' home or the 'file' home; unset = refuse to fly"
    )
    home_tolerance: float = Field(
        5.0, gt=0, description="m horizontally the file's home may lie from the vehicle's"
    )
    home_altitude_tolerance: float = Field(
        10.0, gt=0, description="m the file's home altitude may differ from the vehicle's"
    )

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

    lat: float = Field(ge=-90, le=90)
    lon: float = Field(ge=-180, le=180)
    alt: float | None = Field(None, gt=0, description="m above home; default: cruise_altitude")


def _waypoint_kind(value: Any) -> str:
    return "geo" if isinstance(value, (Mapping, GeoWaypoint)) else "enu"


def _above_home(wp: tuple[float, float, float]) -> tuple[float, float, float]:
    if wp[2] <= 0:
        raise ValueError(f"altitude must be > 0 m above home, got {wp[2]}")
    return wp


Waypoint = Annotated[
    Annotated[tuple[float, float, float], AfterValidator(_above_home), Tag("enu")]
    | Annotated[GeoWaypoint, Tag("geo")],
    Discriminator(_waypoint_kind),
]


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
    rate: float = Field(2.0, gt=0, le=100, description="perception updates per second, Hz")
    low_altitude_rate: float | None = Field(
        None, gt=0, le=100, description="perception updates per second while the range finder "
        "reads less than low_altitude (Hz): a stereo camera close to the ground gives many frames "
        "during the verification hover; default: rate"
    )
    low_altitude: float = Field(
        15.0, gt=0, description="range-finder height (m AGL) below which low_altitude_rate applies"
    )
    camera: DepthCameraSettings = DepthCameraSettings()
    rangefinder: RangeFinderSettings = RangeFinderSettings()
    elevation_map: ElevationMapSettings = ElevationMapSettings()
    detection: DetectorSettings = DetectorSettings()
    depth_costmap: DepthCostmapSettings = DepthCostmapSettings()
    lidar: LidarSettings = LidarSettings()
    lidar_pca: LidarPcaSettings = LidarPcaSettings()
    scripted: ScriptedSettings = ScriptedSettings()


class Mission(BaseModel):
    """A mission file, validated.

    Waypoints are ENU metres ``[x, y, z]`` (z above home) or ``{lat, lon, alt}`` (degrees,
    alt above home), converted with a local tangent plane about ``home`` in lockstep, about
    the home the vehicle reports on a live link (see :class:`VehicleConfig`).
    ``weights.normaliser`` defaults to ``cruise_altitude`` and ``lsm.verification_altitude``
    to ``landing.verification_altitude``.
    """

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    name: str = ""
    description: str = ""
    vehicle: VehicleConfig = VehicleConfig()
    home: HomeSettings = HomeSettings()
    cruise_altitude: float = Field(100.0, gt=0, description="m above home")
    takeoff_altitude: float | None = Field(
        None, gt=0, description="m above home; default: the first waypoint's altitude"
    )
    waypoints: list[Waypoint] = Field(min_length=1)
    weights: LossWeights = LossWeights()
    lsm: LsmSettings = LsmSettings()
    landing: LandingSettings = LandingSettings()
    world: TerrainSettings = Field(default_factory=_flat_world)
    sitl: SitlSettings = SitlSettings()
    perception: PerceptionConfig = PerceptionConfig()
    sites: list[ScriptedSite] = Field(
        default_factory=list, description="sites of the scripted source"
    )
    seed: int = Field(0, ge=0, description="seeds terrain, sensor noise, wind, pattern centres")
    tick_rate: float = Field(10.0, gt=0, le=1000, description="tree ticks per second, Hz")
    time_limit: float = Field(1800.0, gt=0, description="s of mission time before aborting")

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

    @property
    def has_home(self) -> bool:
        """True when the mission file gives a ``home`` (else it is the default)."""
        return "home" in self.source_data()

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
        waypoints are converted about ``home`` (see :meth:`waypoints_enu`)."""
        return MissionPlan(
            waypoints=self.waypoints_enu(home, project),
            takeoff_altitude=self.takeoff_altitude,
            cruise_altitude=self.cruise_altitude,
            landing=self.landing,
        )

    def source_data(self) -> dict[str, Any]:
        """The mission as the user wrote it (before derived defaults), a deep copy."""
        if self._source:
            return copy.deepcopy(self._source)
        return self.model_dump(exclude_unset=True)


def _positive(value: Any) -> float | None:
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
    cruise = _positive(data.get("cruise_altitude", 100.0))
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
    ver_alt = _positive(ver_alt)
    if ver_alt is not None and (lsm is None or isinstance(lsm, Mapping)):
        lsm = dict(lsm or {})
        lsm.setdefault("verification_altitude", ver_alt)
        data["lsm"] = lsm
    home = data.get("home")
    sitl = data.get("sitl")
    if (isinstance(home, Mapping) and (sitl is None or isinstance(sitl, Mapping))
            and _valid(HomeSettings, home)):
        sitl = dict(sitl or {})  # the simulator's home is the mission's home
        sitl.setdefault("home", dict(home))
        data["sitl"] = sitl
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


def load_mission(path: str | os.PathLike[str]) -> Mission:
    """Read and validate a mission file.

    Raises:
        MissionFileError: (a :class:`~autonomy.errors.UserError`) unreadable file, YAML
            syntax errors, duplicate keys, and every schema problem, one message each as
            ``FILE:LINE: FIELD: REASON``.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise MissionFileError([f"{path}: cannot read mission file: {reason}"]) from None
    mission = parse_mission(text, str(path), base_dir=path.parent)
    if not mission.name:  # reports are titled with the file's name then
        mission = apply_overrides(mission, {"name": path.stem})
    return mission


def parse_mission(text: str, name: str = "<mission>", base_dir: Path | None = None) -> Mission:
    """Validate mission YAML ``text``; ``name`` is used in the messages (see load_mission).

    A relative ``world.path`` (elevation file) is taken relative to ``base_dir`` (the mission
    file's directory) when given.
    """
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else 1
        what = exc.problem or exc.context or "malformed YAML"
        raise MissionFileError([f"{name}:{line}: YAML syntax error: {what}"]) from None
    except yaml.YAMLError as exc:
        raise MissionFileError([f"{name}:1: YAML error: {exc}"]) from None
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
    try:
        mission = Mission.model_validate(data)
    except ValidationError as exc:
        problems += [_locate(err, node, name) for err in exc.errors()]
    if problems:
        raise MissionFileError(sorted(problems, key=_line_of))
    return mission


def _duplicate_keys(root: yaml.Node, name: str) -> list[str]:
    problems = []
    stack: list[tuple[yaml.Node, str]] = [(root, "")]
    while stack:
        node, prefix = stack.pop()
        if isinstance(node, yaml.MappingNode):
            seen: set[Any] = set()
            for key, value in node.value:
                field = f"{prefix}{key.value}"
                if key.value in seen:
                    problems.append(f"{name}:{key.start_mark.line + 1}: {field}: duplicate key")
                seen.add(key.value)
                stack.append((value, field + "."))
        elif isinstance(node, yaml.SequenceNode):
            stack.extend((v, f"{prefix}{i}.") for i, v in enumerate(node.value))
    return problems


def _line_of(message: str) -> int:
    match = re.search(r":(\d+): ", message)
    return int(match.group(1)) if match else 0


def _locate(err: Mapping[str, Any], root: yaml.Node, name: str) -> str:
    """One message for one pydantic error, at the YAML node its location points to."""
    node, mark_node, parts = root, root, []
    loc = list(err.get("loc", ()))
    msg = str(err.get("msg", "invalid")).removeprefix("Value error, ")
    # Model-level checks name the field they are about first ("search_rectangle: ..."):
    # point at that field.
    named = re.match(r"([A-Za-z_][\w.]*): ", msg)
    if named and err.get("type") == "value_error":
        loc += named.group(1).split(".")
        msg = msg[named.end():]
    for i, item in enumerate(loc):
        last = i == len(loc) - 1
        if isinstance(node, yaml.MappingNode) and isinstance(item, str):
            match = next((kv for kv in node.value if kv[0].value == item), None)
            if match is not None:
                parts.append(item)
                key, node = match
                mark_node = key if err.get("type") == "extra_forbidden" and last else node
                continue
            if last:  # a missing field: name it, point at its mapping
                parts.append(item)
            # otherwise a union tag or model name pydantic adds to locations: skip it
        elif isinstance(node, yaml.SequenceNode) and isinstance(item, int):
            if 0 <= item < len(node.value):
                parts.append(str(item))
                node = mark_node = node.value[item]
                continue
            parts.append(str(item))
        elif isinstance(item, int) and isinstance(node, yaml.ScalarNode):
            parts.append(str(item))  # an item of a scalar that should be a list
    field = ".".join(parts) or "(mission)"
    value = err.get("input")
    if err.get("type") == "extra_forbidden":
        msg = "unknown setting"
    elif err.get("type") not in ("missing", "value_error") and isinstance(
        value, (int, float, str, bool)
    ):
        msg = f"{msg} (got {value!r})"
    return f"{name}:{mark_node.start_mark.line + 1}: {field}: {msg}"


# --------------------------------------------------------------------------------------
# Overrides


def apply_overrides(mission: Mission, overrides: Mapping[str, Any]) -> Mission:
    """A copy of ``mission`` with dotted keys set (``{"landing.verification_altitude": 5}``).

    Keys follow the mission file's structure; list items are addressed by index
    (``"sites.0.verifies"``). Derived defaults (e.g. ``weights.normaliser`` from
    ``cruise_altitude``) follow the new values unless the mission set them explicitly.

    Raises:
        UserError: a key the schema does not have, or a value it rejects.
    """
    data = mission.source_data()
    for key, value in overrides.items():
        _set_dotted(data, key, value)
    try:
        return Mission.model_validate(data)
    except ValidationError as exc:
        problems = []
        for err in exc.errors():
            where = ".".join(str(p) for p in err["loc"])
            key = next(
                (k for k in overrides if where == k or where.startswith(k + ".")
                 or k.startswith(where + ".") or _strip_tags(err["loc"], k)),
                None,
            )
            if err["type"] == "extra_forbidden":
                problems.append(f"override {key or where}: unknown setting")
            else:
                problems.append(f"override {key or where}: {err['msg']}")
        raise UserError("; ".join(dict.fromkeys(problems))) from None


def _strip_tags(loc: Sequence[Any], key: str) -> bool:
    """True if ``key``'s parts appear in order in ``loc`` (union tags skipped)."""
    parts = key.split(".")
    it = iter(str(p) for p in loc)
    return all(any(p == q for q in it) for p in parts)


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
