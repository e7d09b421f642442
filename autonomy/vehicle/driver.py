"""The non-blocking MAVLink vehicle driver.

:class:`MavlinkVehicle` satisfies :class:`behaviors.ports.VehiclePort` over any byte
transport (a socket or serial port through pymavlink, or the in-memory link to the embedded
SITL). Nothing here waits: :meth:`MavlinkVehicle.poll` decodes a bounded batch of incoming
bytes into an immutable :class:`~behaviors.ports.VehicleState`, then sends what is due (our
HEARTBEAT, command re-sends, setpoint streams); commands return handles at once.

Lockstep use, once per tick: ``sitl.step(dt); clock.advance(dt); vehicle.poll(); tree.tick()``.

Longer than 500 lines because :class:`MavlinkVehicle` is the whole VehiclePort over one
link's state (decoding, command tracking for two autopilots, setpoint streams); what needs
no link state lives beside it (commands.py, modes.py, frames.py, connection.py).
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.vehicle import fence_steps, frames, modes
from autonomy.vehicle.commands import (
    CommandStep,
    CommandTracker,
    Handle,
    Procedure,
    StepGenerator,
    TrackerSettings,
    Wait,
    finished_handle,
)
from autonomy.vehicle.fence import FenceUpload
from autonomy.vehicle.home import FlightFrame, HomeMove
from autonomy.vehicle.settings import LOG_STREAMS, VehicleLinkSettings
from autonomy.vehicle.tlog import TlogWriter
from autonomy.vehicle.transfers import (
    ItemFields,
    MissionDownload,
    MissionUpload,
    ParamRead,
    ParamSet,
    param_value,
)
from behaviors.ports import Clock, CommandStatus, LandedState, VehicleState
from lsm.area import NoFlyCircle, NoFlyZone
from sitl.copter.codec import (  # pymavlink's codec, byte for byte, in fewer steps
    FastMAVLink,
    MessageRecord,
)

# Longest MAVLink 2 packet (header 10 + payload 255 + crc 2 + signature 13).
_MAX_PACKET = 280
_CHUNK = 4096
_PREARM_TEXT_FRESH = 30.0  # s a PreArm STATUSTEXT stays the reason for a denied arm
_COMPACT_AT = 1 << 16  # bytes consumed in pymavlink's parse buffer before it is compacted
_PREARM_BIT = mavlink.MAV_SYS_STATUS_PREARM_CHECK
# EKF_STATUS_REPORT flags behind ArduPilot's "Need Position Estimate" (Copter's
# ekf_has_absolute_position: disarmed, a predicted position will do; armed, it must be real).
_EKF_POS_ABS = mavlink.EKF_POS_HORIZ_ABS
_EKF_PRED_POS_ABS = mavlink.EKF_PRED_POS_HORIZ_ABS
_EKF_CONST_POS = mavlink.EKF_CONST_POS_MODE
_ARMED_FLAG = mavlink.MAV_MODE_FLAG_SAFETY_ARMED
_SET_POSITION_TARGET = mavlink.MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED
_POSITION_ONLY = 0x0DF8  # ignore velocity, acceleration, yaw, yaw rate
_VELOCITY_ONLY = 0x0DC7  # ignore position, acceleration, yaw, yaw rate
_POSITION_VELOCITY = 0x0DC0  # a trajectory's setpoint: ignore acceleration, yaw, yaw rate
_DOWNWARD = mavlink.MAV_SENSOR_ROTATION_PITCH_270
_LANDED = {
    mavlink.MAV_LANDED_STATE_UNDEFINED: LandedState.UNDEFINED,
    mavlink.MAV_LANDED_STATE_ON_GROUND: LandedState.ON_GROUND,
    mavlink.MAV_LANDED_STATE_IN_AIR: LandedState.IN_AIR,
    mavlink.MAV_LANDED_STATE_TAKEOFF: LandedState.TAKEOFF,
    mavlink.MAV_LANDED_STATE_LANDING: LandedState.LANDING,
}
_MAVLINK_EPOCH = 1420070400.0  # 2015-01-01, origin of MAVLink signing timestamps
_LIGHT_SENSORS = "LASER_RING"  # NAMED_VALUE_INT of the laser light-sensor ring (bit mask)
_SLACK = 1e-6  # s; periods are compared with this slack so float tick sums do not skip one


class Transport(Protocol):
    """A byte pipe to the autopilot; ``read`` never blocks."""

    description: str

    def read(self) -> bytes: ...

    def write(self, data: bytes) -> None: ...

    def close(self) -> None: ...


@dataclass
class LinkStats:
    """What the driver has seen on the link since it was created."""

    bytes_received: int = 0
    messages: int = 0  # packets decoded with a good CRC (and signature, with signing)
    corrupt_bytes: int = 0  # bytes skipped as garbage or failed packets
    corrupt_packets: int = 0
    bad_signature: int = 0
    backlog_dropped_bytes: int = 0  # unread bytes dropped when the backlog overflowed
    ignored: int = 0  # packets from other systems, source 0/0, or before the autopilot spoke
    dropped_sensor: Counter = field(default_factory=Counter)  # bad values, by message type
    messages_sent: int = 0
    read_errors: int = 0
    write_errors: int = 0
    commands_sent: int = 0
    links_lost: int = 0
    heartbeats: int = 0  # autopilot HEARTBEATs of our vehicle
    first_heartbeat: float | None = None  # clock s when the autopilot was first heard
    longest_heartbeat_gap: float = 0.0  # clock s between two autopilot HEARTBEATs
    time_lost: float = 0.0  # clock s with the link lost after first contact (ended losses)


class _Outgoing:
    """The file object pymavlink writes our packets to."""

    __slots__ = ("_vehicle",)

    def __init__(self, vehicle: MavlinkVehicle) -> None:
        self._vehicle = vehicle

    def write(self, buf: bytes) -> None:
        self._vehicle._write(buf)


@dataclass(frozen=True)
class ModeChange:
    """A flight mode change seen in HEARTBEAT; ``requested`` is False for one we did not ask
    for (the operator on another ground station, a failsafe, the autopilot's own sequence)."""

    time: float
    old: str
    new: str
    requested: bool


@dataclass
class _Setpoint:
    kind: str  # "position", "velocity" or "trajectory" (position with velocity feed-forward)
    ned: tuple[float, float, float]
    velocity_ned: tuple[float, float, float] = (0.0, 0.0, 0.0)  # feed-forward, "trajectory"


class MavlinkVehicle:
    """A vehicle driven over MAVLink; satisfies :class:`behaviors.ports.VehiclePort`.

    Args:
        transport: the byte pipe (see :func:`autonomy.vehicle.connect`, which builds one).
        clock: injected time source; every timeout is measured in its seconds.
        settings: :class:`VehicleLinkSettings`; ``link_timeout`` overrides its field.
        signing_key: 32-byte MAVLink 2 signing key; outgoing packets are signed and unsigned
            or badly signed incoming ones are rejected and counted.
        target_system: talk only to this system id (default: the first autopilot heard).
        tlog_path: write a ``.tlog`` of both directions there.
        tlog_epoch: Unix time of clock time 0 in the log (default: wall time now - clock).
        sitl: the embedded simulator behind a ``sim://`` link, exposed as ``vehicle.sitl``.
        owns_sitl: close ``sitl`` with the vehicle.
        on_vehicle_time: called after each poll that decoded a time stamp of the autopilot,
            with the newest one (seconds since it booted: ``time_boot_ms`` / 1000); feeds
            :class:`autonomy.clock.VehicleClock`.
    """

    def __init__(
        self,
        transport: Transport,
        clock: Clock,
        *,
        settings: VehicleLinkSettings | None = None,
        link_timeout: float | None = None,
        signing_key: bytes | None = None,
        target_system: int | None = None,
        tlog_path: str | Path | None = None,
        tlog_epoch: float | None = None,
        sitl: Any = None,
        owns_sitl: bool = False,
        on_vehicle_time: Callable[[float], None] | None = None,
    ) -> None:
        settings = settings or VehicleLinkSettings()
        if link_timeout is not None:
            settings = settings.model_copy(update={"link_timeout": float(link_timeout)})
        self.settings = settings
        self.clock = clock
        self.sitl = sitl
        self._owns_sitl = owns_sitl
        self._transport = transport
        self._on_vehicle_time = on_vehicle_time
        self.stats = LinkStats()
        self.mode_changes: list[ModeChange] = []
        now = clock.now()
        if tlog_epoch is None:
            tlog_epoch = time.time() - now
        self._epoch = tlog_epoch
        self._tlog = TlogWriter(tlog_path, tlog_epoch) if tlog_path is not None else None

        self._mav = FastMAVLink(
            _Outgoing(self), settings.source_system, settings.source_component
        )
        self._mav.robust_parsing = True
        if signing_key is not None:
            if len(signing_key) != 32:
                raise ValueError("a MAVLink signing key is 32 bytes")
            self._mav.signing.secret_key = bytes(signing_key)
            self._mav.signing.sign_outgoing = True
            self._mav.signing.link_id = 0
            self._mav.signing.timestamp = int((tlog_epoch + now - _MAVLINK_EPOCH) * 1e5)
        self._backlog = bytearray()
        self._backlog_pos = 0
        self._tracker = CommandTracker(
            self._send_command,
            TrackerSettings(
                ack_timeout=settings.ack_timeout,
                attempts=settings.command_attempts,
                in_progress_timeout=settings.in_progress_timeout,
                confirm_timeout=settings.confirm_timeout,
                refusal_text_grace=settings.refusal_text_grace,
            ),
        )
        self._procedures: list[Procedure] = []
        # Mission-protocol and parameter exchanges, until done.
        self._transfers: list[MissionUpload | MissionDownload | ParamSet | ParamRead] = []
        self.fence_upload: FenceUpload | None = None  # the last upload_fence(), if any
        self._exchanges = fence_steps.Exchanges(self._upload, self._download, self._read_param,
                                                self._set_param, self._command)

        # What the autopilot last reported (raw, NED where it says so).
        self._wanted_system = target_system
        self._target_system: int | None = None
        self._target_component = 1
        self._autopilot = modes.UNKNOWN
        self._last_heartbeat: float | None = None
        self._armed = False
        self._custom_mode: int | None = None
        self._mode = ""
        self._landed = LandedState.UNDEFINED
        self._battery: float | None = None
        self._gps_fix = 0
        self._position_ned: tuple[float, float, float] | None = None
        self._global_position = False  # a GLOBAL_POSITION_INT with a position arrived
        self._ekf_flags: int | None = None  # EKF_STATUS_REPORT.flags, where the autopilot sends it
        self._velocity_ned = (0.0, 0.0, 0.0)
        self._light_sensors: int | None = None  # NAMED_VALUE_INT LASER_RING (docs/gps-denied.md)
        self._light_sensors_time: float | None = None
        self._yaw_ned = math.pi / 2.0
        self._rangefinder: float | None = None
        self._home: tuple[float, float, float] | None = None  # the vehicle's latest home
        self._frame = FlightFrame()  # the origin of every ENU position (autonomy.vehicle.home)
        self._prearm_present = False
        self._prearm_health = False
        self._status_text = ""
        self._prearm_text = ""
        self._prearm_text_time = -math.inf
        self._link_lost = True
        self._lost_since: float | None = None  # clock s the current loss was declared
        self._requested_modes: dict[str, float] = {}

        self._setpoint: _Setpoint | None = None
        self._following: Handle | None = None  # the handle of the trajectory being tracked
        self._setpoint_since: float | None = None  # clock s when the current stream began
        self._last_setpoint_sent = -math.inf
        self._last_heartbeat_sent = -math.inf

        self._handlers: dict[str, Callable[[Any, float], None]] = {
            "HEARTBEAT": self._on_heartbeat,
            "SYS_STATUS": self._on_sys_status,
            "BATTERY_STATUS": self._on_battery_status,
            "GPS_RAW_INT": self._on_gps_raw_int,
            "LOCAL_POSITION_NED": self._on_local_position_ned,
            "ATTITUDE": self._on_attitude,
            "EXTENDED_SYS_STATE": self._on_extended_sys_state,
            "DISTANCE_SENSOR": self._on_distance_sensor,
            "RANGEFINDER": self._on_rangefinder,
            "HOME_POSITION": self._on_home_position,
            "GLOBAL_POSITION_INT": self._on_global_position_int,
            "EKF_STATUS_REPORT": self._on_ekf_status_report,
            "NAMED_VALUE_INT": self._on_named_value_int,
            "STATUSTEXT": self._on_statustext,
            "COMMAND_ACK": self._on_command_ack,
            "MISSION_REQUEST_INT": self._on_mission_request,
            "MISSION_REQUEST": self._on_mission_request,
            "MISSION_ACK": self._on_mission_ack,
            "MISSION_COUNT": self._on_mission_count,
            "MISSION_ITEM_INT": self._on_mission_item_int,
            "PARAM_VALUE": self._on_param_value,
        }
        # The snapshot built by the last poll(): a plain attribute, not a property, since
        # the tree reads it a dozen times a tick (behaviors.ports.VehiclePort.state).
        self.state = VehicleState(time=now)
        # ArduPilot sends nothing on a link until it hears from a ground station.
        self._send_heartbeat(now)

    # ------------------------------------------------------------------ public: state
    @property
    def autopilot(self) -> str:
        return self._autopilot

    def keep_frame(self) -> None:
        """Keep the flight's ENU frame about the vehicle's current home (or the first one it
        reports): a later home elsewhere is recorded in :attr:`home_moves` and no longer
        moves the positions reported or flown to."""
        self._frame.keep()

    @property
    def home_moves(self) -> list[HomeMove]:
        """The vehicle's home moves since the frame was kept, oldest first."""
        return self._frame.moves

    def time_lost(self) -> float:
        """Clock seconds the link has been lost after first contact, the current loss
        included."""
        ongoing = 0.0 if self._lost_since is None else self.clock.now() - self._lost_since
        return self.stats.time_lost + ongoing

    def longest_heartbeat_gap(self) -> float:
        """Longest clock time between two autopilot HEARTBEATs, the current silence
        included (0 before the first)."""
        if self._last_heartbeat is None:
            return 0.0
        return max(self.stats.longest_heartbeat_gap, self.clock.now() - self._last_heartbeat)

    @property
    def target_system(self) -> int | None:
        """System id of the autopilot we talk to (None until it has been heard)."""
        return self._target_system

    def poll(self) -> VehicleState:
        """Decode what has arrived (at most ``max_messages_per_poll`` packets), advance the
        commands, send what is due, and return the new state snapshot. Never waits."""
        now = self.clock.now()
        self._receive(now)
        self._decode(now)
        was_lost = self._link_lost
        age = math.inf if self._last_heartbeat is None else now - self._last_heartbeat
        self._link_lost = age > self.settings.link_timeout
        if self._link_lost and not was_lost:
            self.stats.links_lost += 1
            self._lost_since = now
            self._on_link_lost(now, age)
        elif was_lost and not self._link_lost:
            # First contact, or the link is back (the autopilot may have rebooted).
            if self._lost_since is not None:
                self.stats.time_lost += now - self._lost_since
                self._lost_since = None
            self._request_streams(now)
        self._tracker.update(now)
        if self._transfers:
            self._update_transfers(now)
        self._advance_procedures(now)
        if now - self._last_heartbeat_sent >= self.settings.heartbeat_period - _SLACK:
            self._send_heartbeat(now)
        self._stream_setpoint(now)
        self.state = self._snapshot(now, age)
        return self.state

    # ------------------------------------------------------------------ public: commands
    def arm(self) -> Handle:
        """Arm the motors. DENIED carries the autopilot's latest PreArm text."""
        return self._start("arm") or self._arm_step(True)

    def disarm(self) -> Handle:
        return self._start("disarm") or self._arm_step(False)

    def set_mode(self, mode: str) -> Handle:
        """Switch to ``mode``, a name of either family ("GUIDED" = "OFFBOARD", "LAND" =
        "AUTO.LAND", ...). ACCEPTED once HEARTBEAT shows the new mode."""
        refused = self._start(f"set_mode {mode}")
        if refused:
            return refused
        now = self.clock.now()
        try:
            request = modes.resolve_mode(self._autopilot, mode)
        except KeyError as exc:
            return finished_handle(f"set_mode {mode}", now, CommandStatus.DENIED, exc.args[0])
        if request.name == modes.guided_mode(self._autopilot):
            if self._setpoint is None:
                self._hold_here()
            return self._procedure(
                f"set_mode {request.name}", self._enter_guided_steps(), kind="guided"
            )
        self._stop_guided(f"set_mode {request.name}")
        return self._mode_step(request.name)

    def takeoff(self, altitude: float) -> Handle:
        """Climb to ``altitude`` m above home: switches mode and arms as needed. ACCEPTED
        when the autopilot has accepted the take-off (watch ``state.position`` for the climb).
        """
        name = f"takeoff {altitude:g} m"
        refused = self._start(name)
        if refused:
            return refused
        if not math.isfinite(altitude) or altitude <= 0:
            return finished_handle(
                name, self.clock.now(), CommandStatus.DENIED, "altitude must be > 0 m"
            )
        # A GUIDED position target would cancel ArduPilot's take-off.
        self._stop_guided("takeoff")
        if self._autopilot == modes.PX4:
            return self._procedure(name, self._px4_takeoff_steps(float(altitude)))
        return self._procedure(name, self._ardupilot_takeoff_steps(float(altitude)))

    def goto(self, x: float, y: float, z: float) -> Handle:
        """Fly to the ENU position (m from home). The target is streamed (re-sent) for as long
        as it is current; ACCEPTED once the autopilot is in GUIDED/OFFBOARD following it."""
        name = f"goto ({x:.1f}, {y:.1f}, {z:.1f})"
        refused = self._start(name)
        if refused:
            return refused
        if not all(math.isfinite(v) for v in (x, y, z)):
            return finished_handle(name, self.clock.now(), CommandStatus.DENIED, "not finite")
        self._set_setpoint("position", frames.enu_to_ned(x, y, z, self._frame.origin_ned))
        return self._procedure(name, self._enter_guided_steps(), kind="guided")

    def set_velocity(self, vx: float, vy: float, vz: float) -> Handle:
        """Fly at the ENU velocity (m/s), streamed like :meth:`goto`."""
        name = f"set_velocity ({vx:.1f}, {vy:.1f}, {vz:.1f})"
        refused = self._start(name)
        if refused:
            return refused
        if not all(math.isfinite(v) for v in (vx, vy, vz)):
            return finished_handle(name, self.clock.now(), CommandStatus.DENIED, "not finite")
        self._set_setpoint("velocity", frames.enu_to_ned_velocity(vx, vy, vz))
        return self._procedure(name, self._enter_guided_steps(), kind="guided")

    def follow(self, x: float, y: float, z: float, vx: float, vy: float, vz: float) -> Handle:
        """Track a trajectory: the ENU position (m from home) with the ENU velocity (m/s) as a
        feed-forward, one sample of a moving target. Call it on every tick with the next
        sample; the setpoint is replaced and streamed at the setpoint rate. The first call
        enters GUIDED/OFFBOARD; later calls while following return the same handle."""
        name = "follow trajectory"
        refused = self._start(name)
        if refused:
            return refused
        if not all(math.isfinite(v) for v in (x, y, z, vx, vy, vz)):
            return finished_handle(name, self.clock.now(), CommandStatus.DENIED, "not finite")
        position = frames.enu_to_ned(x, y, z, self._frame.origin_ned)
        velocity = frames.enu_to_ned_velocity(vx, vy, vz)
        following = self._setpoint is not None and self._setpoint.kind == "trajectory"
        handle = self._following
        if following and handle is not None and handle.status not in (
            CommandStatus.DENIED, CommandStatus.TIMED_OUT
        ):
            # Same stream, next sample: sent at the setpoint rate, not on every call.
            self._setpoint = _Setpoint("trajectory", position, velocity)
            return handle
        self._set_setpoint("trajectory", position, velocity)
        self._following = self._procedure(name, self._enter_guided_steps(), kind="guided")
        return self._following

    def hold(self) -> Handle:
        """Stop and hover: PX4 AUTO.LOITER; ArduPilot GUIDED at the current position."""
        refused = self._start("hold")
        if refused:
            return refused
        if self._autopilot == modes.PX4 or self._position_ned is None:
            self._stop_guided("hold")
            return self._mode_step("AUTO.LOITER" if self._autopilot == modes.PX4 else "LOITER")
        self._hold_here()
        return self._procedure("hold", self._enter_guided_steps(), kind="guided")

    def land(self) -> Handle:
        """Land where the vehicle is: ArduPilot LAND mode, PX4 MAV_CMD_NAV_LAND (AUTO.LAND)."""
        refused = self._start("land")
        if refused:
            return refused
        self._stop_guided("land")
        if self._autopilot == modes.PX4:
            target = modes.resolve_mode(modes.PX4, "AUTO.LAND")
            self._requested_modes[target.name] = self.clock.now()
            nan = math.nan
            return self._submit(
                CommandStep(
                    "land",
                    self.clock.now(),
                    mavlink.MAV_CMD_NAV_LAND,
                    (0.0, 0.0, 0.0, nan, nan, nan, nan),
                    confirm=self._mode_is(target.custom_mode),
                    unconfirmed_reason=self._shown_mode,
                )
            )
        return self._mode_step("LAND")

    def upload_fence(
        self, polygon: list[tuple[float, float]], max_altitude: float | None = None,
        exclusions: Sequence[NoFlyZone] = (),
    ) -> Handle:
        """Make the autopilot enforce the operating area: ``polygon`` (ENU x, y m of the
        flight's frame) uploaded as its inclusion geofence about its home, ``exclusions``
        (polygons, ENU x, y m, and circles) as its no-fly zones, ``max_altitude`` (m above
        home) as its ceiling, and the fence enabled (:mod:`autonomy.vehicle.fence` says what
        is set on each autopilot). ACCEPTED once the autopilot has taken all of it;
        the record is :attr:`fence_upload`."""
        name = f"upload geofence ({len(polygon)} vertices)"
        refused = self._start(name)
        if refused:
            self.fence_upload = FenceUpload(len(polygon), max_altitude, refused)
            return refused
        record = FenceUpload(len(polygon), max_altitude, Handle(name, self.clock.now()),
                             zones=len(exclusions),
                             circles=sum(isinstance(z, NoFlyCircle) for z in exclusions))
        zones = [NoFlyCircle(*map(float, zone)) if isinstance(zone, NoFlyCircle)
                 else [tuple(map(float, v)) for v in zone] for zone in exclusions]

        def steps() -> StepGenerator:
            yield Wait("home position", self.clock.now(), lambda: self._frame.origin is not None,
                       self.settings.link_timeout,
                       "no HOME_POSITION from the autopilot (the fence is placed about home)")
            home = self._frame.origin
            assert home is not None
            yield from fence_steps.upload(
                self._exchanges, record, self._autopilot, (home[0], home[1]),
                [tuple(map(float, v)) for v in polygon], zones, max_altitude)

        record.handle = self._procedure(name, steps())
        self.fence_upload = record
        return record.handle

    def restore_fence(self) -> Handle:
        """Put back what :meth:`upload_fence` changed on the vehicle: its own fence plan
        (as downloaded before the upload), the parameters set (to the values read before),
        and on ArduPilot its fences on or off as FENCE_ENABLE says. ACCEPTED once all is
        back; DENIED at once when no upload was accepted."""
        name = "restore the vehicle's geofence"
        record = self.fence_upload
        if record is None or not record.uploaded:
            return finished_handle(name, self.clock.now(), CommandStatus.DENIED,
                                   "no geofence was uploaded")
        refused = self._start(name)
        if refused:
            record.restore = refused
            return refused
        record.restore = self._procedure(name, fence_steps.restore(self._exchanges, record))
        return record.restore

    def close(self) -> None:
        """Close the link, the telemetry log and an owned simulator; commands still pending
        end as TIMED_OUT."""
        now = self.clock.now()
        for proc in self._procedures:
            proc.cancel("vehicle closed", now, CommandStatus.TIMED_OUT)
        self._procedures.clear()
        self._end_transfers("vehicle closed", now)
        self._tracker.fail_all(CommandStatus.TIMED_OUT, "vehicle closed", now)
        self._clear_setpoint()
        try:
            self._transport.close()
        except OSError:
            pass
        if self._tlog is not None:
            self._tlog.close()
        if self._owns_sitl and self.sitl is not None:
            self.sitl.close()

    def __enter__(self) -> MavlinkVehicle:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ sending
    def _write(self, buf: bytes) -> None:
        """Every packet we send goes here (from pymavlink): to the link and the log."""
        try:
            self._transport.write(bytes(buf))
        except OSError:
            self.stats.write_errors += 1
        self.stats.messages_sent += 1
        if self._tlog is not None:
            self._tlog.write(buf, self.clock.now())

    # ------------------------------------------------------------------ receiving
    def _receive(self, now: float) -> None:
        try:
            data = self._transport.read()
        except OSError:
            data = b""
            self.stats.read_errors += 1
        if not data:
            return
        self.stats.bytes_received += len(data)
        if self._backlog_pos:
            del self._backlog[: self._backlog_pos]
            self._backlog_pos = 0
        self._backlog += data
        excess = len(self._backlog) - self.settings.max_backlog_bytes
        if excess > 0:
            # Keep the newest bytes: a stale backlog is worth less than fresh telemetry.
            del self._backlog[:excess]
            self.stats.backlog_dropped_bytes += excess

    def _decode(self, now: float) -> None:
        mav = self._mav
        budget = self.settings.max_messages_per_poll
        newest_ms = -1  # newest time_boot_ms of our autopilot in this batch
        handlers = self._handlers
        stats = self.stats
        backlog = self._backlog
        read_records = mav.read_records
        tlog = self._tlog
        while budget > 0:
            batch = None
            if mav.buf_index == len(mav.buf) and self._backlog_pos < len(backlog):
                # pymavlink's parser holds nothing: the clean packets next in the backlog are
                # decoded straight into the fields the handlers read, in one call.
                batch, self._backlog_pos = read_records(backlog, self._backlog_pos, budget)
            if not batch:
                if mav.buf_len() < _MAX_PACKET and self._backlog_pos < len(backlog):
                    end = self._backlog_pos + _CHUNK
                    chunk = backlog[self._backlog_pos : end]
                    self._backlog_pos += len(chunk)
                    msg = mav.parse_char(chunk)
                else:
                    msg = mav.parse_char(b"")
                if msg is None:
                    if self._backlog_pos >= len(backlog):
                        break
                    continue
                batch = (msg,)
            budget -= len(batch)
            for msg in batch:
                if isinstance(msg, MessageRecord):  # its type and sender without method calls
                    mtype, src, component = msg._type, msg[-3], msg[-2]
                else:
                    mtype = msg.get_type()
                    if mtype == "BAD_DATA":
                        if msg.reason == "Invalid signature":
                            stats.bad_signature += 1
                        else:
                            stats.corrupt_packets += 1
                            stats.corrupt_bytes += len(msg.data)
                        continue
                    src, component = msg.get_srcSystem(), msg.get_srcComponent()
                stats.messages += 1
                if tlog is not None:
                    tlog.write(msg.get_msgbuf(), now)
                target = self._target_system
                if src != target:
                    if src == 0 or target is not None:
                        stats.ignored += 1
                        continue
                    if mtype != "HEARTBEAT" or not self._adopt(msg):
                        stats.ignored += 1
                        continue
                handler = handlers.get(mtype)
                if handler is not None:
                    handler(msg, now)
                boot_ms = getattr(msg, "time_boot_ms", None)
                if (boot_ms is not None and boot_ms > newest_ms
                        and component == self._target_component):
                    newest_ms = boot_ms
        if newest_ms >= 0 and self._on_vehicle_time is not None:
            self._on_vehicle_time(newest_ms / 1000.0)
        if self._backlog_pos >= len(backlog):
            backlog.clear()
            self._backlog_pos = 0
        if mav.buf_index > _COMPACT_AT:
            # pymavlink only frees its buffer when it is empty; on a stream link (TCP,
            # serial) a packet often straddles two reads, so drop the consumed part here.
            mav.buf = mav.buf[mav.buf_index :]
            mav.buf_index = 0

    def _adopt(self, hb: Any) -> bool:
        """Take the first autopilot HEARTBEAT (of ``target_system``, if given) as our vehicle."""
        if not modes.is_autopilot_heartbeat(hb.autopilot, hb.type):
            return False
        src = hb.get_srcSystem()
        if self._wanted_system is not None and src != self._wanted_system:
            return False
        self._target_system = src
        self._target_component = hb.get_srcComponent()
        return True

    # ------------------------------------------------------------------ message handlers
    def _on_heartbeat(self, hb: Any, now: float) -> None:
        if hb.get_srcComponent() != self._target_component:
            return
        if not modes.is_autopilot_heartbeat(hb.autopilot, hb.type):
            return
        first = self._last_heartbeat is None
        stats = self.stats
        stats.heartbeats += 1
        if first:
            stats.first_heartbeat = now
        else:
            stats.longest_heartbeat_gap = max(
                stats.longest_heartbeat_gap, now - self._last_heartbeat
            )
        self._last_heartbeat = now
        self._autopilot = modes.autopilot_name(hb.autopilot)
        self._armed = bool(hb.base_mode & _ARMED_FLAG)
        self._custom_mode = hb.custom_mode
        name = modes.mode_name(self._autopilot, hb.custom_mode)
        if name != self._mode:
            old = self._mode
            self._mode = name
            if not first:
                self._on_mode_change(now, old, name)

    def _on_mode_change(self, now: float, old: str, new: str) -> None:
        asked = self._requested_modes.get(new)
        window = self.settings.ack_timeout * self.settings.command_attempts
        requested = asked is not None and now - asked <= window + self.settings.confirm_timeout
        self.mode_changes.append(ModeChange(now, old, new, requested))
        guided = modes.guided_mode(self._autopilot)
        if not requested and old == guided and new != guided:
            # Someone else took the vehicle (operator, failsafe): stop pushing our targets.
            self._stop_guided(f"a mode change to {new} not asked for")

    def _on_sys_status(self, msg: Any, now: float) -> None:
        if msg.battery_remaining >= 0:
            self._battery = float(min(msg.battery_remaining, 100))
        self._prearm_present = bool(msg.onboard_control_sensors_present & _PREARM_BIT)
        self._prearm_health = bool(msg.onboard_control_sensors_health & _PREARM_BIT)

    def _on_battery_status(self, msg: Any, now: float) -> None:
        if msg.battery_remaining >= 0:
            self._battery = float(min(msg.battery_remaining, 100))

    def _on_gps_raw_int(self, msg: Any, now: float) -> None:
        self._gps_fix = int(msg.fix_type)

    def _on_local_position_ned(self, msg: Any, now: float) -> None:
        x, y, z, vx, vy, vz = msg.x, msg.y, msg.z, msg.vx, msg.vy, msg.vz
        finite = math.isfinite
        if not (finite(x) and finite(y) and finite(z) and finite(vx) and finite(vy)
                and finite(vz)):
            self.stats.dropped_sensor["LOCAL_POSITION_NED"] += 1
            return
        self._position_ned = (x, y, z)
        self._velocity_ned = (vx, vy, vz)

    def _on_attitude(self, msg: Any, now: float) -> None:
        if not math.isfinite(msg.yaw):
            self.stats.dropped_sensor["ATTITUDE"] += 1
            return
        self._yaw_ned = msg.yaw

    def _on_extended_sys_state(self, msg: Any, now: float) -> None:
        self._landed = _LANDED.get(msg.landed_state, LandedState.UNDEFINED)

    def _on_distance_sensor(self, msg: Any, now: float) -> None:
        if msg.orientation != _DOWNWARD:
            return
        if not msg.min_distance <= msg.current_distance <= msg.max_distance:
            # Out of range: the sensor sees nothing usable.
            self.stats.dropped_sensor["DISTANCE_SENSOR"] += 1
            self._rangefinder = None
            return
        self._rangefinder = msg.current_distance / 100.0

    def _on_rangefinder(self, msg: Any, now: float) -> None:
        if not (math.isfinite(msg.distance) and msg.distance >= 0):
            self.stats.dropped_sensor["RANGEFINDER"] += 1
            return
        self._rangefinder = float(msg.distance)

    def _on_home_position(self, msg: Any, now: float) -> None:
        if not all(math.isfinite(v) for v in (msg.x, msg.y, msg.z)):
            self.stats.dropped_sensor["HOME_POSITION"] += 1
            return
        self._home = (msg.latitude * 1e-7, msg.longitude * 1e-7, msg.altitude * 1e-3)
        self._frame.on_home(self._home, (msg.x, msg.y, msg.z), now)

    def _on_global_position_int(self, msg: Any, now: float) -> None:
        # ArduPilot sends 0, 0 until it knows where it is.
        self._global_position = self._global_position or msg.lat != 0 or msg.lon != 0

    def _on_ekf_status_report(self, msg: Any, now: float) -> None:
        self._ekf_flags = int(msg.flags)

    def _on_named_value_int(self, msg: Any, now: float) -> None:
        name = msg.name
        if isinstance(name, (bytes, bytearray)):
            name = name.decode("ascii", "replace")
        if name.rstrip("\x00") != _LIGHT_SENSORS:
            return
        if not 0 <= msg.value < 1 << 13:
            self.stats.dropped_sensor[_LIGHT_SENSORS] += 1
            return
        self._light_sensors = int(msg.value)
        self._light_sensors_time = now

    def _on_statustext(self, msg: Any, now: float) -> None:
        text = msg.text
        if isinstance(text, (bytes, bytearray)):
            text = text.decode("utf-8", "replace")
        text = text.rstrip("\x00").strip()
        self._status_text = text
        lowered = text.lower()
        prearm = lowered.startswith(("prearm", "preflight", "arm:")) or "arming denied" in lowered
        if prearm:
            self._prearm_text = text
            self._prearm_text_time = now
        if prearm or msg.severity <= mavlink.MAV_SEVERITY_WARNING:
            # ArduPilot often says why it refused just after the COMMAND_ACK.
            self._tracker.on_text(text, now)

    def _on_command_ack(self, msg: Any, now: float) -> None:
        if msg.target_system not in (0, self.settings.source_system):
            return  # the answer to another ground station
        self._tracker.on_ack(msg.command, msg.result, now)

    def _for_us(self, msg: Any) -> bool:
        return (msg.target_system == self.settings.source_system
                and msg.target_component in (0, self.settings.source_component))

    def _mission_transfers(self, msg: Any, kind: type | tuple[type, ...]) -> list[Any]:
        """Our transfers of ``kind`` that a mission-protocol message ``msg`` may answer; none
        when it is addressed to another ground station."""
        if not self._for_us(msg):
            return []
        return [t for t in self._transfers if isinstance(t, kind)]

    def _on_mission_request(self, msg: Any, now: float) -> None:
        for upload in self._mission_transfers(msg, MissionUpload):
            upload.on_request(msg.seq, msg.mission_type, now)

    def _on_mission_ack(self, msg: Any, now: float) -> None:
        for transfer in self._mission_transfers(msg, (MissionUpload, MissionDownload)):
            transfer.on_ack(msg.type, msg.mission_type, now)

    def _on_mission_count(self, msg: Any, now: float) -> None:
        for download in self._mission_transfers(msg, MissionDownload):
            download.on_count(msg.count, msg.mission_type, now)

    def _on_mission_item_int(self, msg: Any, now: float) -> None:
        fields = (msg.frame, msg.command, msg.current, msg.autocontinue, msg.param1,
                  msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z)
        for download in self._mission_transfers(msg, MissionDownload):
            download.on_item(msg.seq, fields, msg.mission_type, now)

    def _on_param_value(self, msg: Any, now: float) -> None:
        # PARAM_VALUE is broadcast (no target): any answer shows the value now in force.
        name = msg.param_id
        if isinstance(name, (bytes, bytearray)):
            name = name.decode("ascii", "replace")
        name = name.rstrip("\x00")
        value = param_value(msg.param_value, msg.param_type, self._autopilot == modes.PX4)
        for transfer in self._transfers:
            if isinstance(transfer, (ParamSet, ParamRead)):
                transfer.on_value(name, value, now)

    # ------------------------------------------------------------------ state snapshot
    def _position_estimate(self) -> bool:
        """Whether the autopilot knows where it is (what GUIDED/OFFBOARD need to arm)."""
        flags = self._ekf_flags
        if flags is not None:
            if self._armed:
                return bool(flags & _EKF_POS_ABS) and not flags & _EKF_CONST_POS
            return bool(flags & (_EKF_POS_ABS | _EKF_PRED_POS_ABS))
        # Autopilots without EKF_STATUS_REPORT (PX4): a home and a position to fly from.
        return self._home is not None and (
            self._position_ned is not None or self._global_position
        )

    def _snapshot(self, now: float, age: float) -> VehicleState:
        position = None
        if self._position_ned is not None:
            position = frames.ned_to_enu(*self._position_ned, self._frame.origin_ned)
        # ArduPilot marks its pre-arm check present, enabled and healthy. PX4 (from 1.14, its
        # health report) sets the bit in health alone, once it could arm in its current mode,
        # and never in present: GPS and a position come seconds earlier, while it still says
        # "Preflight Fail: no heading reference".
        if self._prearm_present or self._autopilot == modes.PX4:
            prearm_ok = self._prearm_health
        else:
            prearm_ok = self._gps_fix >= 3 and position is not None
        return VehicleState(
            time=now,
            position=position,
            velocity=frames.ned_to_enu_velocity(*self._velocity_ned),
            yaw=frames.ned_to_enu_yaw(self._yaw_ned),
            armed=self._armed,
            mode=self._mode,
            landed_state=self._landed,
            battery_percent=self._battery,
            gps_fix=self._gps_fix,
            rangefinder_agl=self._rangefinder,
            home=self._home,
            heartbeat_age=age,
            link_lost=self._link_lost,
            prearm_ok=prearm_ok and not self._link_lost,
            position_estimate=self._position_estimate() and not self._link_lost,
            autopilot=self._autopilot,
            last_status_text=self._status_text,
            light_sensors=self._light_sensors,
            light_sensors_time=self._light_sensors_time,
        )

    # ------------------------------------------------------------------ link upkeep
    def _on_link_lost(self, now: float, age: float) -> None:
        reason = f"link lost (no heartbeat for {age:.1f} s)"
        self._tracker.fail_all(CommandStatus.TIMED_OUT, reason, now)
        for proc in self._procedures:
            proc.cancel(reason, now, CommandStatus.TIMED_OUT)
        self._procedures.clear()
        self._end_transfers(reason, now)
        self._clear_setpoint()

    def _send_heartbeat(self, now: float) -> None:
        self._last_heartbeat_sent = now
        # Packed from its fields (no message object built where the link allows it);
        # MAVLink version 3 is pymavlink's default.
        self._mav.send_fields(mavlink.MAVLINK_MSG_ID_HEARTBEAT, (
            mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0,
            mavlink.MAV_STATE_ACTIVE, 3))

    def _request_streams(self, now: float) -> None:
        streams = dict(self.settings.streams)
        if self._tlog is not None:  # what log viewers draw, only when there is a log
            streams = {**LOG_STREAMS, **streams}
        for name, rate in streams.items():
            msg_id = getattr(mavlink, f"MAVLINK_MSG_ID_{name}")
            interval_us = 1e6 / rate if rate > 0 else -1.0
            self._tracker.submit(
                CommandStep(
                    f"stream {name}",
                    now,
                    mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                    (msg_id, interval_us),
                ),
                now,
            )

    def _send_command(self, step: CommandStep) -> None:
        assert self._target_system is not None
        self.stats.commands_sent += 1
        self._mav.command_long_send(
            self._target_system,
            self._target_component,
            step.command,
            min(step.attempts - 1, 255),
            *step.params,
        )

    # ------------------------------------------------------------------ setpoints
    def _set_setpoint(
        self,
        kind: str,
        ned: tuple[float, float, float],
        velocity_ned: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        if self._setpoint is None:
            self._setpoint_since = self.clock.now()
        self._setpoint = _Setpoint(kind, ned, velocity_ned)
        self._last_setpoint_sent = -math.inf
        self._stream_setpoint(self.clock.now())

    def _stop_guided(self, by: str) -> None:
        """Stop streaming setpoints and end the commands still waiting to follow them."""
        self._clear_setpoint()
        now = self.clock.now()
        for proc in self._procedures:
            if proc.kind == "guided" and not proc.done:
                proc.cancel(f"superseded by {by}", now)

    def _clear_setpoint(self) -> None:
        self._setpoint = None
        self._setpoint_since = None

    def _hold_here(self) -> None:
        if self._position_ned is not None:
            self._set_setpoint("position", self._position_ned)
        else:
            self._set_setpoint("velocity", (0.0, 0.0, 0.0))

    def _streaming_for(self, seconds: float) -> bool:
        return self._setpoint_since is not None and (
            self.clock.now() - self._setpoint_since >= seconds
        )

    def _stream_setpoint(self, now: float) -> None:
        sp = self._setpoint
        if sp is None or self._target_system is None or self._link_lost:
            return
        rate = (
            self.settings.setpoint_rate_px4
            if self._autopilot == modes.PX4
            else self.settings.setpoint_rate_ardupilot
        )
        # Periods are compared with _SLACK so that float sums of tick lengths do not skip one.
        if now - self._last_setpoint_sent < 1.0 / rate - _SLACK:
            return
        self._last_setpoint_sent = now
        x, y, z = sp.ned
        if sp.kind == "position":
            mask, pos, vel = _POSITION_ONLY, (x, y, z), (0.0, 0.0, 0.0)
        elif sp.kind == "trajectory":
            mask, pos, vel = _POSITION_VELOCITY, (x, y, z), sp.velocity_ned
        else:
            mask, pos, vel = _VELOCITY_ONLY, (0.0, 0.0, 0.0), (x, y, z)
        self._mav.send_fields(_SET_POSITION_TARGET, (
            int(now * 1000) & 0xFFFFFFFF, self._target_system, self._target_component,
            mavlink.MAV_FRAME_LOCAL_NED, mask, *pos, *vel, 0.0, 0.0, 0.0, 0.0, 0.0))

    # ------------------------------------------------------------------ transfers
    def _update_transfers(self, now: float) -> None:
        for transfer in self._transfers:
            transfer.update(now)
        self._transfers = [t for t in self._transfers if not t.done]

    def _end_transfers(self, reason: str, now: float) -> None:
        for transfer in self._transfers:
            transfer.cancel(reason, now, CommandStatus.TIMED_OUT)
        self._transfers.clear()

    def _send_transfer(self, name: str, fields: tuple) -> None:
        """A mission-protocol message of a :class:`MissionUpload` or
        :class:`MissionDownload` to our autopilot."""
        assert self._target_system is not None
        target = (self._target_system, self._target_component)
        if name == "MISSION_COUNT":
            self._mav.mission_count_send(*target, *fields)
        elif name == "MISSION_ITEM_INT":
            self._mav.mission_item_int_send(*target, *fields)
        elif name == "MISSION_REQUEST_LIST":
            self._mav.mission_request_list_send(*target, *fields)
        elif name == "MISSION_REQUEST_INT":
            self._mav.mission_request_int_send(*target, *fields)
        else:
            self._mav.mission_ack_send(*target, *fields)

    def _send_param_set(self, param: str, value: float, param_type: int) -> None:
        assert self._target_system is not None
        self._mav.param_set_send(self._target_system, self._target_component,
                                 param.encode("ascii"), value, param_type)

    def _set_param(self, param: str, value: float, param_type: int) -> ParamSet:
        now = self.clock.now()
        step = ParamSet(now, param, value, param_type, self._send_param_set,
                        timeout=self.settings.ack_timeout,
                        attempts=self.settings.command_attempts).start(now)
        self._transfers.append(step)
        return step

    def _read_param(self, param: str) -> ParamRead:
        now = self.clock.now()
        step = ParamRead(now, param, self._send_param_read, timeout=self.settings.ack_timeout,
                         attempts=self.settings.command_attempts).start(now)
        self._transfers.append(step)
        return step

    def _send_param_read(self, param: str) -> None:
        assert self._target_system is not None
        self._mav.param_request_read_send(self._target_system, self._target_component,
                                          param.encode("ascii"), -1)

    def _upload(self, name: str, items: list[ItemFields], mission_type: int) -> MissionUpload:
        now = self.clock.now()
        upload = MissionUpload(name, now, items, mission_type, self._send_transfer).start(now)
        self._transfers.append(upload)
        return upload

    def _download(self, name: str, mission_type: int) -> MissionDownload:
        now = self.clock.now()
        download = MissionDownload(name, now, mission_type, self._send_transfer).start(now)
        self._transfers.append(download)
        return download

    def _command(self, name: str, command: int, params: tuple[float, ...]) -> CommandStep:
        return self._submit(CommandStep(name, self.clock.now(), command, params))

    # ------------------------------------------------------------------ command building
    def _start(self, name: str) -> Handle | None:
        """A finished handle if the command cannot start now (link lost), else None."""
        if self._link_lost or self._target_system is None:
            why = "link lost" if self._last_heartbeat is not None else "no autopilot heard yet"
            return finished_handle(name, self.clock.now(), CommandStatus.TIMED_OUT, why)
        return None

    def _submit(self, step: CommandStep) -> CommandStep:
        return self._tracker.submit(step, self.clock.now())

    def _procedure(self, name: str, steps: StepGenerator, kind: str = "") -> Procedure:
        proc = Procedure(name, self.clock.now(), steps, kind=kind)
        proc.advance(self.clock.now())
        if not proc.done:
            self._procedures.append(proc)
        return proc

    def _advance_procedures(self, now: float) -> None:
        if not self._procedures:
            return
        for proc in self._procedures:
            proc.advance(now)
        self._procedures = [p for p in self._procedures if not p.done]

    def _mode_is(self, custom_mode: int) -> Callable[[], bool]:
        if self._autopilot == modes.PX4:
            # PX4 fills the low bytes with flags of its own; main and sub mode name the mode.
            return lambda: (
                self._custom_mode is not None
                and (self._custom_mode & 0xFFFF0000) == (custom_mode & 0xFFFF0000)
            )
        return lambda: self._custom_mode == custom_mode

    def _shown_mode(self) -> str:
        return f"; the autopilot stayed in {self._mode or 'an unknown mode'}"

    def _mode_step(self, name: str) -> Handle:
        now = self.clock.now()
        request = modes.resolve_mode(self._autopilot, name)
        done = self._mode_is(request.custom_mode)
        if done():
            return finished_handle(f"set_mode {request.name}", now, CommandStatus.ACCEPTED)
        self._requested_modes[request.name] = now
        return self._submit(
            CommandStep(
                f"set_mode {request.name}",
                now,
                mavlink.MAV_CMD_DO_SET_MODE,
                (mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, request.param2, request.param3),
                confirm=done,
                unconfirmed_reason=self._shown_mode,
            )
        )

    def _arm_step(self, arm: bool) -> Handle:
        now = self.clock.now()
        if self._armed == arm:
            return finished_handle("arm" if arm else "disarm", now, CommandStatus.ACCEPTED)
        return self._submit(
            CommandStep(
                "arm" if arm else "disarm",
                now,
                mavlink.MAV_CMD_COMPONENT_ARM_DISARM,
                (1.0 if arm else 0.0,),
                confirm=(lambda: self._armed) if arm else (lambda: not self._armed),
                denied_reason=self._recent_prearm_text if arm else None,
            )
        )

    def _recent_prearm_text(self) -> str:
        # ArduPilot repeats failing PreArm checks every 30 s; an older text may be stale.
        if self.clock.now() - self._prearm_text_time <= _PREARM_TEXT_FRESH:
            return self._prearm_text
        return ""

    def _enter_guided_steps(self) -> StepGenerator:
        guided = modes.guided_mode(self._autopilot)
        if self._mode == guided:
            return
        if self._autopilot == modes.PX4:
            # PX4 refuses OFFBOARD unless setpoints are already streaming.
            lead = self.settings.offboard_prestream
            yield Wait(
                "stream setpoints",
                self.clock.now(),
                lambda: self._streaming_for(lead),
                lead + self.settings.link_timeout,
                "setpoint stream stopped before OFFBOARD",
            )
        yield self._mode_step(guided)

    def _ardupilot_takeoff_steps(self, altitude: float) -> StepGenerator:
        yield self._mode_step("GUIDED")
        yield self._arm_step(True)
        yield self._submit(
            CommandStep(
                "NAV_TAKEOFF",
                self.clock.now(),
                mavlink.MAV_CMD_NAV_TAKEOFF,
                (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, altitude),
            )
        )

    def _px4_takeoff_steps(self, altitude: float) -> StepGenerator:
        yield Wait(
            "home position",
            self.clock.now(),
            lambda: self._home is not None,
            self.settings.link_timeout,
            "no HOME_POSITION from the autopilot",
        )
        yield self._arm_step(True)
        home = self._frame.origin or self._home  # "altitude m above home": the flight's
        assert home is not None
        nan = math.nan
        self._requested_modes["AUTO.TAKEOFF"] = self.clock.now()
        yield self._submit(
            CommandStep(
                "NAV_TAKEOFF",
                self.clock.now(),
                mavlink.MAV_CMD_NAV_TAKEOFF,
                (-1.0, 0.0, 0.0, nan, nan, nan, home[2] + altitude),
            )
        )
