"""GPS-denied landing guided by a ground laser (Lee et al., Sensors 2019, sections 3.2, 4.1).

When the GPS fix is lost the vehicle no longer knows where it is, so every position target
is a guess; it still knows its velocity (optical flow), its heading (compass) and its height
above the ground (range finder). An operator on the ground aims a laser at it; the ring of
light sensors says where the light comes from (:mod:`guidance.detector`), the guiding
direction estimator (:mod:`guidance.direction`, the paper's Algorithm 1) filters that
bearing, and :class:`LaserGuidance` flies along it by velocity commands:

1. hover (zero velocity) and wait for the laser, ``wait_timeout`` s at most;
2. fly along the estimated bearing at ``speed`` once the filter has evidence for it (at
   least ``min_updates`` readings, 70 % of the last ten within 45 deg of the bearing the
   filter held before each, and the particles' concentration at least
   ``min_concentration``); hover whenever the light is gone for a moment;
3. descend at ``descent_speed`` while the light comes from below (the downward sensor: the
   vehicle is over the emitter), steering again when it comes from the side;
4. succeed once over the emitter within ``land_height`` m of the ground (the tree then
   lands with :class:`behaviors.flight.Land`, outcome hint "laser_guidance").

Light counts as the laser only when the filter has that evidence and the reading agrees
with it, or when it comes from below; a momentary reflection from elsewhere is fed
to the filter but neither starts the guidance nor keeps it alive. It gives up (FAILURE,
with the reason) at once when no light-sensor reading ever arrived (the vehicle has no ring:
nothing to wait for), when no laser came within ``wait_timeout``, when the light was gone for
``lost_timeout`` (the emitter is behind terrain, the operator stopped), or
when the whole guidance took longer than ``timeout``; the tree then lands in place. Once it
gave up it stays failed, so the tree never flies a bearing it has no evidence for.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from py_trees.common import Access, Status
from pydantic import BaseModel, ConfigDict, Field

from behaviors import blackboard as keys
from behaviors.base import VehicleAction
from behaviors.ports import Clock, VehiclePort
from behaviors.ticking import QuietBehaviour
from guidance import DirectionEstimatorSettings, GuidingDirectionEstimator
from guidance.detector import ring_bearing

RING_MASK = (1 << 12) - 1
DOWN_BIT = 1 << 12
OUTCOME = "laser_guidance"
"""OUTCOME_HINT of a landing the laser guided (the tree's Land writes it)."""
_MAX_WAIT = 3_600.0  # s, as behaviors.settings.MAX_WAIT
# A reading within this angle of the estimate is the laser (neighbours lit at range and the
# 30 deg sectors keep the laser's own readings well inside it).
_CONSISTENT = math.radians(45.0)
# Of the last _WINDOW lit readings, this share must agree with the filter's prior bearing:
# a reflection lands within 45 deg of it one time in four, the laser nearly always.
_WINDOW = 10
_AGREEMENT = 0.7


class LaserGuidanceSettings(BaseModel):
    """Laser guidance after a GPS loss (docs/gps-denied.md)."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    enabled: bool = Field(
        True, description="on a GPS loss, wait for a ground laser and follow it before "
        "landing in place; false lands in place at once"
    )
    wait_timeout: float = Field(
        30.0, gt=0, le=_MAX_WAIT, description="s of clock time to hover waiting for the laser "
        "before landing in place, up to an hour"
    )
    lost_timeout: float = Field(
        15.0, gt=0, le=_MAX_WAIT, description="s without light, once guided, before landing "
        "in place, up to an hour"
    )
    timeout: float = Field(
        900.0, gt=0, le=_MAX_WAIT, description="s of clock time the whole guidance may take, "
        "up to an hour"
    )
    speed: float = Field(
        3.0, gt=0, le=20, description="m/s flown along the laser's bearing, up to 20"
    )
    descent_speed: float = Field(
        1.0, gt=0, le=10, description="m/s of descent while the light comes from below, up to 10"
    )
    land_height: float = Field(
        3.0, gt=0, le=100, description="m above the ground (range finder) at which the vehicle, "
        "over the emitter, hands over to the autopilot's LAND, up to 100"
    )
    light_gap: float = Field(
        1.0, gt=0, le=60, description="s without light after which the vehicle hovers until it "
        "is back, up to a minute"
    )
    particles: int = Field(500, ge=10, le=100_000, description="N_s of the estimator")
    dispersion: float = Field(
        0.10, ge=0, lt=1, description="share of the particles dispersed over the circle after "
        "each resampling (0.1 in the paper)"
    )
    min_updates: int = Field(
        5, ge=1, le=1000, description="laser readings before the first bearing is flown"
    )
    min_concentration: float = Field(
        0.5, ge=0, le=1, description="length of the particles' mean unit vector below which "
        "the bearing is not trusted (hover instead), 0..1"
    )


class LaserGuidance(VehicleAction):
    """Fly to a ground laser by velocity commands and land over it (see the module docstring).

    * SUCCESS: over the emitter, ``land_height`` m above the ground; latched: it succeeds
      at once when ticked again
    * FAILURE: no laser in time, the light lost too long, the guidance too long, a command
      denied; latched: it fails at once when ticked again
    * RUNNING: hovering, flying or descending
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        settings: LaserGuidanceSettings | None = None,
        *,
        rng: np.random.Generator | None = None,
        command_timeout: float = 5.0,
    ) -> None:
        super().__init__(name, vehicle, clock, command_timeout=command_timeout, phase="failsafe")
        self.settings = settings or LaserGuidanceSettings()
        # The estimator's own generator (the tree passes one spawned from the mission's).
        self.rng = rng if rng is not None else np.random.default_rng(0)
        self.gave_up: str | None = None
        self.arrived = False
        self.estimator: GuidingDirectionEstimator | None = None

    def initialise(self) -> None:
        super().initialise()
        if self.gave_up is not None or self.arrived:
            return
        s = self.settings
        self.estimator = GuidingDirectionEstimator(
            DirectionEstimatorSettings(n_particles=s.particles, dispersion_fraction=s.dispersion),
            self.rng,
        )
        self.started = self.clock.now()
        self.last_light: float | None = None
        self.last_reading: float | None = None
        self.below = False
        self.agreement: deque[bool] = deque(maxlen=_WINDOW)
        self.velocity: tuple[float, float, float] | None = None
        if self.vehicle.state.light_sensors_time is not None:
            self._fly((0.0, 0.0, 0.0))

    def _fly(self, velocity: tuple[float, float, float]) -> None:
        """Command ``velocity`` (ENU m/s) unless it is what the vehicle already flies."""
        old = self.velocity
        if old is not None and math.dist(old, velocity) < 0.05 * self.settings.speed:
            return
        self.velocity = velocity
        self.command(self.vehicle.set_velocity(*velocity))

    def _give_up(self, reason: str) -> Status:
        self.gave_up = reason
        return self.fail(reason)

    def _read_light(self, now: float) -> None:
        """Feed a new light-sensor reading (if one arrived) to the detector and the filter."""
        state = self.vehicle.state
        if state.light_sensors_time is None or state.light_sensors_time == self.last_reading:
            return
        self.last_reading = state.light_sensors_time
        mask = state.light_sensors or 0
        self.below = bool(mask & DOWN_BIT)
        body = ring_bearing(mask & RING_MASK)
        if self.below:
            self.last_light = now  # reflections light the ring, not the downward sensor
            return
        if body is None:
            return
        # Body bearings run clockwise from the nose; ENU angles counter-clockwise.
        measured = state.yaw - body
        est = self.estimator
        prior = est.bearing
        agrees = False
        if prior is not None:
            agrees = abs((measured - prior + math.pi) % (2.0 * math.pi) - math.pi) <= _CONSISTENT
        self.agreement.append(agrees)
        est.update(measured)
        # Light counts as the laser only where the readings keep agreeing with the filter: a
        # momentary reflection from another direction neither starts nor prolongs guidance.
        if self._settled() and agrees:
            self.last_light = now

    def _settled(self) -> bool:
        """The filter has evidence for a bearing: enough readings, most of the recent ones
        agreeing with what it believed before them, and its particles concentrated."""
        s = self.settings
        recent = self.agreement
        return (
            len(recent) >= s.min_updates
            and sum(recent) >= _AGREEMENT * len(recent)
            and self.estimator.concentration >= s.min_concentration
        )

    def update(self) -> Status:
        if self.gave_up is not None:
            return self.fail(self.gave_up)
        if self.vehicle.state.light_sensors_time is None:
            # No ring on this vehicle (no reading ever came): nothing to wait for.
            return self._give_up("no light sensors report on this vehicle")
        if self.arrived:
            self.feedback_message = "over the laser"
            return Status.SUCCESS
        s = self.settings
        state = self.vehicle.state
        now = self.clock.now()
        problem = self.command_problem()
        if problem is not None:
            return self._give_up(problem)
        if now - self.started > s.timeout:
            return self._give_up(f"not over the laser within {s.timeout:g} s")
        self._read_light(now)
        if self.last_light is None:
            if now - self.started > s.wait_timeout:
                return self._give_up(f"no laser within {s.wait_timeout:g} s")
            self.feedback_message = "hovering, waiting for the laser"
            return Status.RUNNING
        dark = now - self.last_light
        if dark > s.lost_timeout:
            return self._give_up(f"laser lost for {dark:.0f} s")
        if dark > s.light_gap:
            self._fly((0.0, 0.0, 0.0))
            self.feedback_message = f"hovering, no light for {dark:.1f} s"
            return Status.RUNNING
        if self.below:
            agl = state.rangefinder_agl
            if agl is not None and agl <= s.land_height:
                self.arrived = True
                self.feedback_message = f"over the laser at {agl:.1f} m"
                return Status.SUCCESS
            self._fly((0.0, 0.0, -s.descent_speed))
            self.feedback_message = "light from below: descending"
            return Status.RUNNING
        est = self.estimator
        if not self._settled():
            self._fly((0.0, 0.0, 0.0))
            self.feedback_message = (
                f"hovering, bearing not settled ({est.updates} readings, "
                f"concentration {est.concentration:.2f})"
            )
            return Status.RUNNING
        bearing = est.bearing
        self._fly((s.speed * math.cos(bearing), s.speed * math.sin(bearing), 0.0))
        self.feedback_message = f"following the laser, bearing {math.degrees(bearing):.0f} deg"
        return Status.RUNNING

class FailsafeIs(QuietBehaviour):
    """Condition: the latched failsafe (FAILSAFE) is ``kind``.

    * SUCCESS: FAILSAFE == ``kind``
    * FAILURE: another failsafe, or none
    """

    def __init__(self, name: str, kind: str) -> None:
        super().__init__(name=name)
        self.kind = kind
        self.blackboard = self.attach_blackboard_client(name)
        self.blackboard.register_key(key=keys.FAILSAFE, access=Access.READ)

    def update(self) -> Status:
        failsafe = self.blackboard.get(keys.FAILSAFE)
        self.feedback_message = f"failsafe {failsafe}"
        return Status.SUCCESS if failsafe == self.kind else Status.FAILURE


class BatteryAbove(QuietBehaviour):
    """Condition: the battery is above ``level`` percent (or unknown): a guard that hands the
    vehicle to the critical-battery landing the moment the level is reached.

    * SUCCESS: battery unknown or > ``level`` %
    * FAILURE: battery <= ``level`` %
    """

    def __init__(self, name: str, vehicle: VehiclePort, level: float) -> None:
        super().__init__(name=name)
        self.vehicle = vehicle
        self.level = float(level)

    def update(self) -> Status:
        battery = self.vehicle.state.battery_percent
        if battery is not None and battery <= self.level:
            self.feedback_message = f"battery at or below {self.level:g} %"
            return Status.FAILURE
        return Status.SUCCESS
