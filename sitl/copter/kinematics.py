"""Kinematic multicopter: a position/velocity controller with speed and acceleration limits
flying through wind, resting on the terrain when it touches it.

The state is a handful of scalars, so it is kept in Python floats (a numpy call per scalar costs
more than the arithmetic). Positions and velocities are local ENU metres and m/s; heading is the
MAVLink one (radians clockwise from north).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

GRAVITY = 9.80665  # m/s^2

# Controller gains: position error -> velocity (1/s), velocity error -> acceleration (1/s),
# its integral -> acceleration (1/s^2) up to a limit (m/s^2). Roughly ArduPilot's PSC_POSXY_P,
# PSC_VELXY_P, PSC_VELXY_I and a fifth of PSC_VELXY_IMAX.
_KP_XY = 1.0
_KV_XY = 3.0
_KI_XY = 1.0
_IMAX_XY = 2.0
_KP_Z = 1.0
_KV_Z = 4.0
_KYAW = 2.0
# Above the ground by more than this (m), the vehicle is airborne.
_LIFTOFF_MARGIN = 0.05


@dataclass(slots=True)
class Setpoint:
    """What the flight controller is asked to hold this step.

    position: ENU metres to reach, or None; velocity: ENU m/s (a feed-forward when a position
    is given, the target otherwise), or None; neither = hold still. yaw: heading to turn to
    (rad clockwise from north) or None; yaw_rate: rad/s or None. max_descent, max_climb: m/s
    overriding the airframe limits (LAND's slow final descent), or None. hold_ground: stay on
    the ground even if the target is above it (ArduPilot GUIDED before a takeoff command).
    """

    position: tuple[float, float, float] | None = None
    velocity: tuple[float, float, float] | None = None
    yaw: float | None = None
    yaw_rate: float | None = None
    max_descent: float | None = None
    max_climb: float | None = None
    max_speed: float | None = None
    hold_ground: bool = False


@dataclass(frozen=True, slots=True)
class Contact:
    """The moment the vehicle touched the ground: ENU position (m) and velocity (m/s)."""

    x: float
    y: float
    z: float
    vx: float
    vy: float
    vz: float

    @property
    def speed(self) -> float:
        return math.sqrt(self.vx * self.vx + self.vy * self.vy + self.vz * self.vz)


class Multicopter:
    """Point-mass multicopter with a cascaded position (P) / velocity (PI) controller and the
    airframe's limits. The velocity loop's integrator learns the steady push of the wind, as
    ArduPilot's does, so a hover or a landing holds its point in a steady wind.

    Args:
        max_horizontal_speed, max_climb_speed, max_descent_speed: m/s.
        max_horizontal_acceleration, max_vertical_acceleration: m/s^2.
        max_yaw_rate: rad/s.
        drag: 1/s, how hard the air pulls the vehicle's velocity toward the wind's.
    """

    def __init__(
        self,
        *,
        max_horizontal_speed: float,
        max_climb_speed: float,
        max_descent_speed: float,
        max_horizontal_acceleration: float,
        max_vertical_acceleration: float,
        max_yaw_rate: float,
        drag: float,
        position: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        self.max_horizontal_speed = max_horizontal_speed
        self.max_climb_speed = max_climb_speed
        self.max_descent_speed = max_descent_speed
        self.max_horizontal_acceleration = max_horizontal_acceleration
        self.max_vertical_acceleration = max_vertical_acceleration
        self.max_yaw_rate = max_yaw_rate
        self.drag = drag
        self.x, self.y, self.z = (float(c) for c in position)
        self.vx = self.vy = self.vz = 0.0
        # Thrust acceleration (ENU, without gravity) of the last step: gives the attitude.
        self.ax = self.ay = self.az = 0.0
        # Velocity-loop integrator (ENU m/s^2): cleared whenever the vehicle rests.
        self.ix = self.iy = 0.0
        self.heading = 0.0
        self.yaw_speed = 0.0
        self.on_ground = True
        self.motors_on = False

    @property
    def position(self) -> tuple[float, float, float]:
        return (self.x, self.y, self.z)

    @property
    def velocity(self) -> tuple[float, float, float]:
        return (self.vx, self.vy, self.vz)

    def attitude(self) -> tuple[float, float]:
        """(roll, pitch) in radians (FRD body, MAVLink convention) tilting the thrust."""
        # Body-forward and body-right components of the horizontal thrust acceleration.
        an, ae = self.ay, self.ax
        c, s = math.cos(self.heading), math.sin(self.heading)
        forward = an * c + ae * s
        right = -an * s + ae * c
        up = GRAVITY + self.az
        return math.atan2(right, up), -math.atan2(forward, up)

    def step(
        self, dt: float, setpoint: Setpoint, wind: tuple[float, float], ground: float
    ) -> Contact | None:
        """Advance ``dt`` seconds. ``wind`` is the ENU (east, north) air velocity, m/s;
        ``ground`` the terrain height below the vehicle (ENU z, m). Returns the
        :class:`Contact` if the vehicle touched down during this step, else None."""
        vx, vy, vz = self.vx, self.vy, self.vz
        wx, wy = wind
        if not self.motors_on:
            self.ix = self.iy = 0.0
            if self.on_ground:
                self.vx = self.vy = self.vz = 0.0
                self.ax = self.ay = self.az = 0.0
                self.yaw_speed = 0.0
                return None
            # Motors off in the air: it falls.
            ax, ay, az = 0.0, 0.0, -GRAVITY
            self.ax = self.ay = self.az = 0.0
        else:
            dvx, dvy, dvz = self._desired_velocity(setpoint)
            if self.on_ground and (setpoint.hold_ground or dvz <= 0.0):
                # Resting on the ground at idle: the controller does not push it around.
                self.vx = self.vy = self.vz = 0.0
                self.ax = self.ay = self.az = 0.0
                self.ix = self.iy = 0.0
                self._turn(dt, setpoint)
                return None
            # Velocity loop: P with drag feed-forward on the vehicle's own velocity (it cannot
            # see the wind) plus the integrator, which takes up the wind's steady push.
            ex, ey = dvx - vx, dvy - vy
            ax = _KV_XY * ex + self.drag * vx + self.ix
            ay = _KV_XY * ey + self.drag * vy + self.iy
            az = _KV_Z * (dvz - vz)
            ah = math.hypot(ax, ay)
            amax = self.max_horizontal_acceleration
            if ah > amax:
                ax *= amax / ah
                ay *= amax / ah
            else:  # integrate only while unsaturated (no wind-up during hard manoeuvres)
                ix, iy = self.ix + _KI_XY * ex * dt, self.iy + _KI_XY * ey * dt
                ih = math.hypot(ix, iy)
                if ih > _IMAX_XY:
                    ix, iy = ix * _IMAX_XY / ih, iy * _IMAX_XY / ih
                self.ix, self.iy = ix, iy
            azmax = self.max_vertical_acceleration
            az = min(max(az, -azmax), azmax)
            self.ax, self.ay, self.az = ax, ay, az
            self._turn(dt, setpoint)
        # Air drag toward the wind (the vehicle's thrust acceleration is already in ax, ay).
        ax += self.drag * (wx - vx)
        ay += self.drag * (wy - vy)
        vx += ax * dt
        vy += ay * dt
        vz += az * dt
        self.x += vx * dt
        self.y += vy * dt
        self.z += vz * dt
        self.vx, self.vy, self.vz = vx, vy, vz
        if self.z <= ground:
            contact = None
            if not self.on_ground:
                contact = Contact(self.x, self.y, ground, vx, vy, vz)
            self.z = ground
            self.vx = self.vy = self.vz = 0.0
            self.on_ground = True
            return contact
        if self.z > ground + _LIFTOFF_MARGIN:
            self.on_ground = False
        return None

    def _desired_velocity(self, sp: Setpoint) -> tuple[float, float, float]:
        """The position loop: a square-root controller that brakes within the limits."""
        vmax = self.max_horizontal_speed if sp.max_speed is None else sp.max_speed
        climb = self.max_climb_speed if sp.max_climb is None else sp.max_climb
        descent = self.max_descent_speed if sp.max_descent is None else sp.max_descent
        if sp.position is not None:
            ex = sp.position[0] - self.x
            ey = sp.position[1] - self.y
            ez = sp.position[2] - self.z
            dist = math.hypot(ex, ey)
            if dist > 1e-9:
                brake = math.sqrt(2.0 * self.max_horizontal_acceleration * dist)
                speed = min(vmax, _KP_XY * dist, brake)
                dvx, dvy = ex / dist * speed, ey / dist * speed
            else:
                dvx = dvy = 0.0
            aabs = abs(ez)
            dvz = math.copysign(
                min(_KP_Z * aabs, math.sqrt(2.0 * self.max_vertical_acceleration * aabs)), ez
            )
            if sp.velocity is not None:
                dvx += sp.velocity[0]
                dvy += sp.velocity[1]
                dvz += sp.velocity[2]
        elif sp.velocity is not None:
            dvx, dvy, dvz = sp.velocity
        else:
            dvx = dvy = dvz = 0.0
        sh = math.hypot(dvx, dvy)
        if sh > vmax:
            dvx *= vmax / sh
            dvy *= vmax / sh
        dvz = min(max(dvz, -descent), climb)
        return dvx, dvy, dvz

    def _turn(self, dt: float, sp: Setpoint) -> None:
        rate = 0.0
        if sp.yaw is not None:
            err = (sp.yaw - self.heading + math.pi) % (2.0 * math.pi) - math.pi
            rate = _KYAW * err
        elif sp.yaw_rate is not None:
            rate = sp.yaw_rate
        rate = min(max(rate, -self.max_yaw_rate), self.max_yaw_rate)
        self.yaw_speed = rate
        self.heading = (self.heading + rate * dt + math.pi) % (2.0 * math.pi) - math.pi
