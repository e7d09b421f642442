"""The embedded SITL: a simulated multicopter that speaks MAVLink over byte links."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from sitl.sensors.laser import MESSAGE_NAME, LightSensorRing
from sitl.terrain.moving_hits import obstacle_below, top_below

from .battery import Battery
from .geo import GeoFrame, heading_to_enu_yaw
from .gps import GpsOutage
from .kinematics import Multicopter
from .personalities import PERSONALITIES
from .server import MavlinkServer
from .settings import HomeChangeSettings, SitlSettings
from .wind import Wind

# Stream keys of the generators of the optional GPS drift and light sensors (mixed with the
# seed, so they never share draws with the wind).
_GPS_STREAM = 0x6770
_LASER_STREAM = 0x1A5E


def round_ns(t: float) -> float:
    """``round(t, 9)``, bit for bit, in a third of its time when ``t`` is near a whole
    number of nanoseconds (a sum of ticks always is).

    ``round`` rounds the exact value of ``t * 10**9`` to an integer n and returns the double
    nearest n / 10**9. The product in doubles is within half its ulp of the exact one, so
    when it lies within 0.25 of an integer (and below 10**15, where its ulp is at most 0.125)
    that integer is n; the division of two exact doubles (n < 2**53) is correctly rounded,
    as ``round``'s decimal conversion is. Otherwise ``round`` itself decides."""
    y = t * 1e9
    if -1e15 < y < 1e15:
        n = round(y)
        if n and -0.25 <= y - n <= 0.25:  # (n = 0: round keeps the sign of a zero)
            return n / 1e9
    return round(t, 9)


class Touchdown(NamedTuple):
    """Where and how fast the vehicle last touched the ground: ENU metres, speed m/s."""

    x: float
    y: float
    z: float
    speed: float


class TickTruth(NamedTuple):
    """What a lockstep runner reads of the ground truth on every tick (see
    :meth:`Sitl.tick_truth`): the fields of :class:`TruthState` of the same names."""

    position: tuple[float, float, float]
    battery_percent: float
    touchdown: Touchdown | None
    crashed: bool
    crash_reason: str


@dataclass(slots=True)
class TruthState:
    """Ground truth of the simulated vehicle, for reports and tests (not sent over MAVLink);
    a new one on every read of :attr:`Sitl.truth`, not changed after (not frozen: a frozen
    dataclass sets each field through ``object.__setattr__``, and the runner reads the truth
    on every tick).

    position: ENU m; velocity: ENU m/s; yaw: rad ENU (counter-clockwise from east);
    mode: flight mode name of the personality ("GUIDED", "AUTO.LOITER", ...);
    landed: resting on the ground; touchdown: the last touchdown after a flight, or None;
    touchdown_vertical_speed (m/s, down > 0) and touchdown_slope_deg of that touchdown.
    """

    time: float
    position: tuple[float, float, float]
    velocity: tuple[float, float, float]
    yaw: float
    armed: bool
    mode: str
    landed: bool
    crashed: bool
    crash_reason: str
    battery_percent: float
    touchdown: Touchdown | None
    touchdown_vertical_speed: float | None
    touchdown_slope_deg: float | None
    ground_height: float
    wind: tuple[float, float]


class Sitl:
    """A multicopter simulator that speaks MAVLink 2 like ArduPilot Copter (or PX4).

    Args:
        settings: airframe, world and link settings; defaults if None.
        terrain: any object with ``height(x, y) -> ndarray`` (vectorised, ENU metres);
            None = flat ground at z = 0.
        autopilot: personality, ``"ardupilot"`` or ``"px4"``.
        seed: seeds the wind gusts (and, when configured, the GPS drift and light sensors,
            from generators of their own so an ordinary flight draws exactly as before).
        signing_key: 32-byte MAVLink 2 signing key in force from boot: packets are signed and
            unsigned ones refused (None: unsigned until a SETUP_SIGNING sets a key).

    Time is simulated: :meth:`step` reads what arrived on the attached links, handles it,
    integrates the model for ``dt`` seconds and sends the telemetry that fell due.
    """

    def __init__(
        self,
        settings: SitlSettings | None = None,
        *,
        terrain=None,
        autopilot: str = "ardupilot",
        seed: int = 0,
        signing_key: bytes | None = None,
    ) -> None:
        if autopilot not in PERSONALITIES:
            known = ", ".join(sorted(PERSONALITIES))
            raise ValueError(f"autopilot: unknown personality {autopilot!r} (known: {known})")
        if terrain is not None and not callable(getattr(terrain, "height", None)):
            raise TypeError("terrain: needs a height(x, y) method (or None for flat ground)")
        if signing_key is not None and len(signing_key) != 32:
            raise ValueError("signing_key: a MAVLink signing key is 32 bytes")
        s = settings if settings is not None else SitlSettings()
        self.terrain = terrain
        # A Terrain's scalar lookup, faster than its vectorised height() for one point.
        self._height_at = None if terrain is None else getattr(terrain, "height_at", None)
        self._time = 0.0
        self._closed = False
        home_z = self._height(0.0, 0.0)
        self.model = Multicopter(
            max_horizontal_speed=s.max_horizontal_speed,
            max_climb_speed=s.max_climb_speed,
            max_descent_speed=s.max_descent_speed,
            max_horizontal_acceleration=s.max_horizontal_acceleration,
            max_vertical_acceleration=s.max_vertical_acceleration,
            max_yaw_rate=math.radians(s.max_yaw_rate),
            drag=s.drag,
            position=(0.0, 0.0, home_z),
        )
        self.battery = Battery(s.battery)
        self.wind = Wind(s.wind, np.random.default_rng(seed))
        geo = GeoFrame(s.home.lat, s.home.lon, s.home.alt, home_z, self._height, autopilot)
        self.autopilot = PERSONALITIES[autopilot](
            s, self.model, self.battery, self.slope, ground_z=home_z, geo=geo
        )
        self._ground = self._ground_now = home_z
        # GPS-denied flight (docs/gps-denied.md): nothing is built, nothing drawn, unless the
        # settings ask for it.
        if s.gps_loss is not None:
            self.autopilot.gps = GpsOutage(s.gps_loss, np.random.default_rng([seed, _GPS_STREAM]))
        self.light_sensors: LightSensorRing | None = None
        self.light_sensor_mask = 0  # the last reading (bit mask, sitl.sensors.laser)
        self._light_due = 0.0
        if s.laser is not None:
            self.light_sensors = LightSensorRing(
                s.laser, self._heights, np.random.default_rng([seed, _LASER_STREAM])
            )
        self._ground_xy = (0.0, 0.0)
        self._home_change_sent = False
        self.home_change_result: int | None = None  # the MAV_RESULT of the scheduled one
        self._touchdown_of = self._touchdown = None  # the autopilot's, as a Touchdown
        self.server = MavlinkServer(
            self.autopilot,
            self._agl,
            streams_by_default=autopilot == "px4",
            signing_key=signing_key,
        )

    @property
    def settings(self) -> SitlSettings:
        """The settings in force (a parameter set over MAVLink changes them)."""
        return self.autopilot.settings

    # ------------------------------------------------------------------ terrain
    def _height(self, x: float, y: float) -> float:
        if self.terrain is None:
            return 0.0
        at = self._height_at
        h = (
            at(x, y) if at is not None
            else float(np.asarray(self.terrain.height(np.array([x]), np.array([y]))).ravel()[0])
        )
        # A terrain without data here (NaN) keeps the last known ground under the vehicle.
        return h if math.isfinite(h) else getattr(self, "_ground", 0.0)

    def _heights(self, x, y) -> np.ndarray:
        """Vectorised terrain height (flat ground: zeros)."""
        if self.terrain is None:
            return np.zeros(np.broadcast(np.asarray(x), np.asarray(y)).shape)
        return np.asarray(self.terrain.height(x, y), dtype=np.float64)

    def slope(self, x: float, y: float) -> float:
        """Terrain slope at (x, y) in degrees, by central differences over
        ``settings.slope_baseline`` metres."""
        if self.terrain is None:
            return 0.0
        b = self.settings.slope_baseline
        xs = np.array([x + b, x - b, x, x])
        ys = np.array([y, y, y + b, y - b])
        h = np.asarray(self.terrain.height(xs, ys), dtype=np.float64).ravel()
        gx = (h[0] - h[1]) / (2.0 * b)
        gy = (h[2] - h[3]) / (2.0 * b)
        return math.degrees(math.atan(math.hypot(gx, gy)))

    def _agl(self) -> float:
        """Height above the terrain right below the vehicle now (for the rangefinder)."""
        m = self.model
        if (m.x, m.y) != self._ground_xy:
            self._ground_xy = (m.x, m.y)
            self._ground_now = self._height(m.x, m.y)
        moving = getattr(self.terrain, "moving", None)
        if moving is not None:  # a person or a car under the vehicle returns first
            return min(m.z - self._ground_now, obstacle_below(moving, (m.x, m.y, m.z),
                                                              self._time))
        return m.z - self._ground_now

    # --------------------------------------------------------------------- API
    @property
    def time(self) -> float:
        """Simulated seconds since boot."""
        return self._time

    @property
    def personality(self) -> str:
        return self.autopilot.name

    def attach(self, endpoint) -> None:
        """Serve MAVLink on ``endpoint`` (anything with ``read() -> bytes`` and
        ``write(bytes)``, e.g. :attr:`sitl.link.MemoryLink.vehicle`)."""
        self.server.attach(endpoint)

    def detach(self, endpoint) -> None:
        """Stop serving ``endpoint``."""
        self.server.detach(endpoint)

    @property
    def corrupt_bytes(self) -> int:
        """Bytes skipped on the links because they did not parse as MAVLink."""
        return self.server.corrupt_bytes

    def step(self, dt: float) -> None:
        """Advance simulated time by ``dt`` seconds: handle incoming bytes, integrate the
        model in steps of at most ``settings.physics_step``, emit due telemetry."""
        if self._closed:
            raise RuntimeError("the SITL is closed")
        if not dt >= 0.0 or not math.isfinite(dt):
            raise ValueError(f"dt: must be a finite number >= 0, got {dt}")
        ap = self.autopilot
        model = self.model
        battery = self.battery
        ap.time = self._time
        self.server.receive()
        if dt > 0.0:
            n = max(1, math.ceil(dt / self.settings.physics_step - 1e-9))
            h = dt / n
            if (model.x, model.y) == self._ground_xy:  # _agl looked it up after the last step
                ground = self._ground = self._ground_now
            else:
                ground = self._ground = self._height(model.x, model.y)
            moving = getattr(self.terrain, "moving", None)
            if moving is not None:  # a car's roof under the vehicle is what it lands on
                ground = max(ground, top_below(moving, model.position, self._time))
            wind = self.wind.advance(dt)
            t0 = self._time
            for i in range(1, n + 1):
                sp = ap.control(model.z - ground)
                contact = model.step(h, sp, wind, ground)
                # Rounded to the nanosecond: sums of ticks stay clean (10.0, not 10.000...07).
                self._time = ap.time = round_ns(t0 + i * h)
                if contact is not None:
                    ap.on_contact(contact)
                if ap.gps is not None:
                    ap.update_gps(h)
                flying = model.motors_on and not model.on_ground
                battery.drain(
                    h, flying=flying, climb_rate=model.vz, speed=math.hypot(model.vx, model.vy)
                )
                ap.after_step()
        if self.light_sensors is not None and self._time + 1e-9 >= self._light_due:
            self._read_light_sensors()
        change = self.settings.home_change
        if change is not None and not self._home_change_sent and self._time + 1e-9 >= change.at:
            self._send_home_change(change)
        self.server.emit(self._time)

    def _send_home_change(self, change: HomeChangeSettings) -> None:
        """The scheduled DO_SET_HOME of a ground station: home on the ground at the point."""
        self._home_change_sent = True
        ap = self.autopilot
        lat, lon = ap.geo.to_global(change.east, change.north)
        ground = float(self._height(change.east, change.north))
        alt = self.settings.home.alt + ground - ap.origin_z
        result = self.server.commands.set_home_to(lat, lon, alt)
        self.home_change_result = result

    def _read_light_sensors(self) -> None:
        """One reading of the light-sensor ring, sent as NAMED_VALUE_INT."""
        ring = self.light_sensors
        m = self.model
        period = 1.0 / ring.settings.rate
        self._light_due = max(self._light_due + period, self._time)
        self.light_sensor_mask = ring.read(m.position, m.heading)
        self.server.send_named_value_int(MESSAGE_NAME, self.light_sensor_mask, self._time)

    @property
    def truth(self) -> TruthState:
        ap = self.autopilot
        m = self.model
        td = ap.touchdown
        agl = self._agl()
        return TruthState(
            time=self._time,
            position=m.position,
            velocity=m.velocity,
            yaw=heading_to_enu_yaw(m.heading),
            armed=ap.armed,
            mode=ap.mode,
            landed=m.on_ground,
            crashed=ap.crashed,
            crash_reason=ap.crash_reason,
            battery_percent=self.battery.percent,
            touchdown=None if td is None else Touchdown(td.x, td.y, td.z, td.speed),
            touchdown_vertical_speed=None if td is None else td.vertical_speed,
            touchdown_slope_deg=None if td is None else td.slope_deg,
            ground_height=m.z - agl,
            wind=self.wind.velocity,
        )

    def tick_truth(self) -> TickTruth:
        """The part of :attr:`truth` a runner records on every tick, without the rest (the
        height above ground, the wind, the velocity), which costs as much again."""
        ap = self.autopilot
        m = self.model
        td = ap.touchdown
        if td is not None and td is not self._touchdown_of:
            self._touchdown_of = td
            self._touchdown = Touchdown(td.x, td.y, td.z, td.speed)
        return TickTruth((m.x, m.y, m.z), self.battery.percent,
                         None if td is None else self._touchdown, ap.crashed, ap.crash_reason)

    def close(self) -> None:
        """Stop serving all links (closing those that can be closed)."""
        for link in self.server.links:
            close = getattr(link.endpoint, "close", None)
            if close is not None:
                close()
        self.server.links.clear()
        self._closed = True

    def __enter__(self) -> Sitl:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
