"""Flight behaviours: preflight checks, takeoff, waypoint navigation, descent, landing."""

from __future__ import annotations

from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.base import MissionBehaviour, Point, RouteAction, VehicleAction
from behaviors.ports import Clock, CommandHandle, CommandStatus, LandedState, VehiclePort
from lsm.area import NoFlyCircle, OperatingArea

GPS_FIX_3D = 3


class Preflight(MissionBehaviour):
    """Wait until the vehicle is ready to fly: link up, position known, 3D GPS fix, the
    autopilot's own position estimate (ArduPilot judges its prearm bit for the current mode,
    e.g. STABILIZE, and still refuses to arm in GUIDED without one), prearm ok.

    With a ``fence`` (the operating area, when the mission uploads it: ``geofence.upload``)
    it then has the autopilot enforce it (``vehicle.upload_fence``), once per flight; else it
    sends no command. Wrap it in :class:`behaviors.decorators.ClockTimeout` to bound the wait.

    * SUCCESS: every check passes (and the fence is on the autopilot)
    * FAILURE: the battery is already at or below ``battery_reserve`` percent, or the
      autopilot refused the fence or did not answer (taking off without the fence the
      mission asked for would fly the area unguarded; ``geofence.upload: false`` flies
      without it)
    * RUNNING: waiting; the feedback message lists what is missing
    """

    def __init__(
        self, name: str, vehicle: VehiclePort, *, battery_reserve: float | None = None,
        fence: OperatingArea | None = None,
    ) -> None:
        super().__init__(name, phase="preflight")
        self.vehicle = vehicle
        self.battery_reserve = battery_reserve
        self.fence = fence
        self._fence_handle: CommandHandle | None = None  # kept once accepted: uploaded once

    def initialise(self) -> None:
        super().initialise()
        handle = self._fence_handle
        if handle is not None and handle.status is not CommandStatus.ACCEPTED:
            self._fence_handle = None  # re-entered (the link came back): upload again

    def update(self) -> Status:
        state = self.vehicle.state
        battery = state.battery_percent
        if (
            self.battery_reserve is not None
            and battery is not None
            and battery <= self.battery_reserve
        ):
            return self.fail(
                f"battery {battery:.0f} % at or below the reserve {self.battery_reserve:.0f} %"
            )
        missing = []
        if state.link_lost:
            missing.append("link")
        if state.position is None:
            missing.append("position")
        if state.gps_fix < GPS_FIX_3D:
            missing.append(f"3D GPS fix (fix type {state.gps_fix})")
        if not (state.position_estimate or state.armed):
            missing.append("the autopilot's position estimate")
        if not (state.prearm_ok or state.armed):  # armed already: the checks were passed
            text = f" ({state.last_status_text})" if state.last_status_text else ""
            missing.append(f"prearm checks{text}")
        if missing:
            self.feedback_message = "waiting for " + ", ".join(missing)
            return Status.RUNNING
        if self.fence is not None:
            handle = self._fence_handle
            if handle is None:
                handle = self._fence_handle = self.vehicle.upload_fence(
                    list(self.fence.vertices), self.fence.max_altitude,
                    exclusions=[zone if isinstance(zone, NoFlyCircle) else list(zone)
                                for zone in self.fence.exclusions])
            if not handle.status.done:
                self.feedback_message = "uploading the geofence to the autopilot"
                return Status.RUNNING
            if handle.status is not CommandStatus.ACCEPTED:
                return self.fail(f"geofence not uploaded ({handle.status.value}): "
                                 f"{handle.reason}")
        self.feedback_message = "ready"
        return Status.SUCCESS


class Takeoff(VehicleAction):
    """Take off vertically to ``altitude`` m above home (the vehicle arms as needed).

    A vehicle already flying (armed, in the air or taking off: a mission started in flight,
    or a take-off restarted after the link came back) climbs with a goto instead, since
    autopilots refuse a take-off in the air.

    * SUCCESS: within ``acceptance_radius`` below (or above) the altitude
    * FAILURE: the takeoff command was denied or not answered (the autopilot's reason)
    * RUNNING: climbing
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        altitude: float,
        *,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
    ) -> None:
        super().__init__(name, vehicle, clock, command_timeout=command_timeout, phase="takeoff")
        self.altitude = float(altitude)
        self.acceptance_radius = float(acceptance_radius)

    def initialise(self) -> None:
        super().initialise()
        state = self.vehicle.state
        flying = state.landed_state in (LandedState.IN_AIR, LandedState.TAKEOFF)
        if state.armed and flying and state.position:
            x, y, _ = state.position
            self.command(self.vehicle.goto(x, y, self.altitude))
        else:
            self.command(self.vehicle.takeoff(self.altitude))

    def update(self) -> Status:
        position = self.vehicle.state.position
        if position is not None and position[2] >= self.altitude - self.acceptance_radius:
            self.feedback_message = f"at {position[2]:.1f} m"
            return Status.SUCCESS
        problem = self.command_problem()
        if problem is not None:
            return self.fail(problem)
        if position is None:
            self.feedback_later("climbing to {:.1f} m, at unknown", self.altitude)
        else:
            self.feedback_later("climbing to {:.1f} m, at {:.1f} m", self.altitude, position[2])
        return Status.RUNNING


class NavigateToWaypoint(RouteAction):
    """Fly to an ENU waypoint; with a clear altitude, climb to it first, traverse, then
    reach the waypoint's altitude.

    The traverse altitude is ``max(clear_altitude, current z)``: already higher is already
    clear. Without a clear altitude the vehicle flies straight to the waypoint.

    * SUCCESS: inside ``acceptance_radius`` of the waypoint
    * FAILURE: a goto denied or unanswered (the autopilot's reason); bound the flight time
      with :class:`behaviors.decorators.ClockTimeout`
    * RUNNING: flying
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        waypoint: Point | None = None,
        *,
        clear_altitude: float | None = None,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
        phase: str | None = "mission",
    ) -> None:
        super().__init__(
            name,
            vehicle,
            clock,
            acceptance_radius=acceptance_radius,
            command_timeout=command_timeout,
            phase=phase,
        )
        self.waypoint = None if waypoint is None else tuple(float(v) for v in waypoint)
        self.clear_altitude = clear_altitude

    def target(self) -> tuple[Point, float | None] | str:
        """The waypoint and clear altitude to use now, or why there is none."""
        if self.waypoint is None:
            return "no waypoint"
        return self.waypoint, self.clear_altitude

    def plan_route(self, position: Point) -> list[Point] | str:
        target = self.target()
        if isinstance(target, str):
            return target
        (x, y, z), clear = target
        if clear is None:
            return [(x, y, z)]
        traverse = max(clear, position[2])
        return [(position[0], position[1], traverse), (x, y, traverse), (x, y, z)]


class NavigateToSite(NavigateToWaypoint):
    """Fly over the chosen landing site at the clear altitude (both read from the
    blackboard): climb to the clear altitude, traverse, arrive over the site.

    * SUCCESS: over the site at the clear altitude
    * FAILURE: no site or clear altitude on the blackboard, or a goto denied / unanswered
    * RUNNING: flying
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        *,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
        site_key: str = keys.LANDING_SITE,
        clear_altitude_key: str = keys.CLEAR_ALTITUDE,
    ) -> None:
        super().__init__(
            name,
            vehicle,
            clock,
            acceptance_radius=acceptance_radius,
            command_timeout=command_timeout,
            phase="navigate_to_site",
        )
        self.site_key = site_key
        self.clear_altitude_key = clear_altitude_key
        self.blackboard.register_key(key=site_key, access=Access.READ)
        self.blackboard.register_key(key=clear_altitude_key, access=Access.READ)

    def target(self) -> tuple[Point, float | None] | str:
        site = self.blackboard.get(self.site_key)
        clear = self.blackboard.get(self.clear_altitude_key)
        if site is None or clear is None:
            return "no landing site chosen"
        return (site.x, site.y, clear), clear


class ChangeAltitudeLS(RouteAction):
    """Descend (or climb) to ``height`` m above the chosen site, over the site: the blind
    descent to the verification altitude (z_site + 2.5 m by default).

    * SUCCESS: at the height above the site
    * FAILURE: no site on the blackboard, or a goto denied / unanswered
    * RUNNING: moving
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        height: float,
        *,
        acceptance_radius: float = 1.0,
        command_timeout: float = 5.0,
        phase: str = "descend",
        site_key: str = keys.LANDING_SITE,
    ) -> None:
        super().__init__(
            name,
            vehicle,
            clock,
            acceptance_radius=acceptance_radius,
            command_timeout=command_timeout,
            phase=phase,
        )
        self.height = float(height)
        self.site_key = site_key
        self.blackboard.register_key(key=site_key, access=Access.READ)

    def plan_route(self, position: Point) -> list[Point] | str:
        site = self.blackboard.get(self.site_key)
        if site is None:
            return "no landing site chosen"
        return [(site.x, site.y, site.z + self.height)]


class Land(VehicleAction):
    """Land where the vehicle is and wait for touchdown and disarm.

    On entry it writes its phase and, when given, ``outcome_hint`` to
    :data:`behaviors.blackboard.OUTCOME_HINT`. If the vehicle sits on the ground still armed
    for ``command_timeout`` seconds it sends a disarm (autopilots usually disarm alone).

    * SUCCESS: disarmed and not in the air (phase becomes "done", FAILURE_REASON is cleared:
      failures recovered from on the way do not make a landed mission a failed one)
    * FAILURE: the land (or disarm) command was denied or not answered
    * RUNNING: descending / waiting for the disarm
    """

    def __init__(
        self,
        name: str,
        vehicle: VehiclePort,
        clock: Clock,
        *,
        phase: str = "land",
        outcome_hint: str | None = None,
        command_timeout: float = 5.0,
    ) -> None:
        super().__init__(name, vehicle, clock, command_timeout=command_timeout, phase=phase)
        self.outcome_hint = outcome_hint
        self.blackboard.register_key(key=keys.OUTCOME_HINT, access=Access.WRITE)
        self.on_ground_since: float | None = None
        self.disarm_sent = False

    def initialise(self) -> None:
        super().initialise()
        if self.outcome_hint is not None:
            self.blackboard.set(keys.OUTCOME_HINT, self.outcome_hint)
        self.on_ground_since = None
        self.disarm_sent = False
        self.command(self.vehicle.land())

    def update(self) -> Status:
        state = self.vehicle.state
        grounded = state.landed_state in (LandedState.ON_GROUND, LandedState.UNDEFINED)
        if not state.armed and grounded:
            self.blackboard.set(keys.PHASE, "done")
            self.blackboard.set(keys.FAILURE_REASON, None)
            self.feedback_message = "landed and disarmed"
            return Status.SUCCESS
        problem = self.command_problem()
        if problem is not None:
            return self.fail(problem)
        if state.landed_state is LandedState.ON_GROUND:
            now = self.clock.now()
            if self.on_ground_since is None:
                self.on_ground_since = now
            elif not self.disarm_sent and now - self.on_ground_since > self.command_timeout:
                self.command(self.vehicle.disarm())
                self.disarm_sent = True
            self.feedback_message = "on the ground, waiting for the disarm"
        else:
            self.on_ground_since = None
            height = "" if state.position is None else f" at {state.position[2]:.1f} m"
            self.feedback_message = f"landing{height}"
        return Status.RUNNING
