"""What the behaviours need from the outside world, as ports.

The MAVLink driver in :mod:`autonomy` satisfies :class:`VehiclePort`; tests use fakes.
All positions are local ENU metres (origin at home, z up), velocities ENU m/s, yaw radians
(ENU, counter-clockwise from east), time in seconds of the injected :class:`Clock`.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from lsm.area import NoFlyZone


class Clock(Protocol):
    """Injected time source: simulated time in lockstep runs, the vehicle's own time live."""

    def now(self) -> float: ...


class CommandStatus(enum.Enum):
    """Life cycle of a vehicle command."""

    PENDING = "pending"  # queued or sent, no answer yet
    ACCEPTED = "accepted"  # the autopilot accepted it (COMMAND_ACK ACCEPTED, or confirmed)
    IN_PROGRESS = "in_progress"  # the autopilot reported it is working on it
    DENIED = "denied"  # refused; ``reason`` carries the autopilot's words
    TIMED_OUT = "timed_out"  # no answer within the timeout (clock time)

    @property
    def done(self) -> bool:
        return self in (CommandStatus.ACCEPTED, CommandStatus.DENIED, CommandStatus.TIMED_OUT)


@runtime_checkable
class CommandHandle(Protocol):
    """A command's progress, polled by behaviours."""

    @property
    def name(self) -> str: ...

    @property
    def status(self) -> CommandStatus: ...

    @property
    def reason(self) -> str:
        """Why it was denied or timed out (the autopilot's STATUSTEXT / ACK result); ''."""
        ...


class LandedState(enum.Enum):
    UNDEFINED = "undefined"
    ON_GROUND = "on_ground"
    IN_AIR = "in_air"
    TAKEOFF = "takeoff"
    LANDING = "landing"


@dataclass(slots=True)
class VehicleState:
    """Snapshot of what the autopilot last reported; the driver makes a new one on every
    poll and nobody changes one after (not frozen: a frozen dataclass sets each field
    through ``object.__setattr__``, and a snapshot is made on every tick)."""

    time: float = 0.0  # clock seconds when the snapshot was taken
    position: tuple[float, float, float] | None = None  # ENU m; None until known
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)  # ENU m/s
    yaw: float = 0.0  # rad, ENU
    armed: bool = False
    mode: str = ""  # flight mode by name, e.g. "GUIDED", "LAND", "OFFBOARD", "AUTO.LAND"
    landed_state: LandedState = LandedState.UNDEFINED
    battery_percent: float | None = None  # 0..100
    gps_fix: int = 0  # GPS_FIX_TYPE (3 = 3D)
    rangefinder_agl: float | None = None  # m above ground from the downward rangefinder
    home: tuple[float, float, float] | None = None  # lat deg, lon deg, alt m AMSL
    heartbeat_age: float = float("inf")  # s since the last autopilot HEARTBEAT
    link_lost: bool = True
    prearm_ok: bool = False
    position_estimate: bool = False  # the autopilot knows where it is (GUIDED needs it to arm)
    autopilot: str = "unknown"  # "ardupilot", "px4" or "unknown"
    last_status_text: str = ""
    # The laser light sensors (docs/gps-denied.md): bit i = ring sensor i (i * 30 deg
    # clockwise from the nose), bit 12 = downward sensor; None until a reading arrived.
    light_sensors: int | None = None
    light_sensors_time: float | None = None  # clock s the last reading arrived


class VehiclePort(Protocol):
    """Non-blocking vehicle commands; each returns a handle to poll."""

    @property
    def state(self) -> VehicleState: ...

    def arm(self) -> CommandHandle: ...

    def disarm(self) -> CommandHandle: ...

    def set_mode(self, mode: str) -> CommandHandle: ...

    def takeoff(self, altitude: float) -> CommandHandle:
        """Climb to ``altitude`` metres above home (arms and switches mode as needed)."""
        ...

    def goto(self, x: float, y: float, z: float) -> CommandHandle:
        """Fly to an ENU position (re-sent by the driver as the autopilot requires)."""
        ...

    def set_velocity(self, vx: float, vy: float, vz: float) -> CommandHandle: ...

    def follow(
        self, x: float, y: float, z: float, vx: float, vy: float, vz: float
    ) -> CommandHandle:
        """Track a trajectory: call on every tick with its next ENU position (m) and
        velocity (m/s, a feed-forward); later calls while following return the same handle."""
        ...

    def hold(self) -> CommandHandle: ...

    def land(self) -> CommandHandle: ...

    def upload_fence(
        self, polygon: list[tuple[float, float]], max_altitude: float | None = None,
        exclusions: Sequence[NoFlyZone] = (),
    ) -> CommandHandle:
        """Make the autopilot itself enforce the operating area: ``polygon`` (ENU x, y m)
        as its inclusion geofence, each of ``exclusions`` (ENU x, y m polygons, or circles) as
        a no-fly zone, ``max_altitude`` (m above home) as its ceiling, enabled.
        Only called when the mission asks for it (``geofence.upload``)."""
        ...


class Trajectory(Protocol):
    """A planned flight in time: ENU positions (m) and velocities (m/s) from t = 0 s."""

    @property
    def duration(self) -> float: ...

    def state_at(self, t: float) -> tuple[tuple[float, float, float], tuple[float, float, float]]:
        """(position, velocity) at ``t`` seconds from the start (held at the end)."""
        ...


class ApproachPlanner(Protocol):
    """Plans the approach to a site over what the vehicle knows of the terrain."""

    def plan(
        self, start: tuple[float, float, float], goal: tuple[float, float, float]
    ) -> Trajectory | str:
        """A collision-free trajectory from ``start`` to ``goal`` (ENU m; it may end higher
        over the goal, to keep its margin over the terrain), or why there is none (the
        caller then flies the climb, traverse and descent instead)."""
        ...


@dataclass(frozen=True, slots=True)
class ObstacleSighting:
    """What the descent camera's optical flow said about one pair of consecutive frames.

    ``away`` is in image axes (x right, y up, the camera's top edge towards the vehicle's
    nose) and ``yaw`` is the heading (rad, ENU) the newer frame was taken with; together
    they give the ENU direction away from the obstacle.
    """

    time: float  # clock seconds of the newer frame
    obstacle: bool  # some direction holds an obstacle (Algorithm 2)
    away: tuple[float, float] = (0.0, 0.0)  # unit vector, image axes; zeros if none
    yaw: float = 0.0  # rad, ENU
    directions: tuple[str, ...] = ()  # the flagged directions, e.g. ("upper right",)


class ObstacleWatch(Protocol):
    """The optical-flow watch of the descent camera (seed 004)."""

    def watch(self, on: bool) -> None:
        """Start (True) or stop (False) comparing frames; frames from before a start are
        never compared with frames after it."""
        ...

    def latest(self) -> ObstacleSighting | None:
        """The newest sighting since watching started, or None."""
        ...
