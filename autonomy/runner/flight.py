"""One flight: the per-tick loop that connects vehicle, perception, LSM and tree.

Per tick (DESIGN.md section 6, lockstep): advance the simulator and the clock, poll the
vehicle, tell the LSM where the drone is, at the perception rate feed the source's
observations to the LSM, tick the tree, record. :class:`Flight` does everything after the
clock advance (and holds the mission while the link is lost, see
:mod:`autonomy.runner.link`); :mod:`autonomy.runner.run` and :mod:`autonomy.runner.live`
drive it.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from typing import IO, Any

import py_trees

from autonomy.report.data import FlightTrace
from autonomy.report.events import EventLog, TreeStatusRecorder
from autonomy.runner.link import Link, LinkWatch
from behaviors import blackboard as bb
from behaviors.ports import CommandStatus, LandedState
from lsm import LandingSiteManager

Status = py_trees.common.Status


class PhaseConsole:
    """The live console view: one line each time the mission phase changes."""

    def __init__(self, stream: IO[str] | None = None,
                 before_line: Callable[[], None] | None = None) -> None:
        self._stream = stream or sys.stdout
        self.before_line = before_line  # e.g. clear a progress line on the same terminal

    def phase(self, t: float, phase: str, altitude: float | None, sites: int,
              best_loss: float | None, battery: float | None) -> None:
        alt = "   -  " if altitude is None else f"{altitude:6.1f}"
        loss = "   -  " if best_loss is None else f"{best_loss:6.3f}"
        batt = "  -" if battery is None else f"{battery:3.0f}"
        if self.before_line is not None:
            self.before_line()
        print(
            f"[{t:7.1f} s] {phase:<17} alt {alt} m  sites {sites:3d}  best loss {loss}"
            f"  battery {batt} %",
            file=self._stream, flush=True,
        )

    def note(self, t: float, text: str) -> None:
        """A line about something other than the phase (the link, the homes), at once."""
        if self.before_line is not None:
            self.before_line()
        print(f"[{t:7.1f} s] {text}", file=self._stream, flush=True)


class Flight:
    """The wiring of one flight, ticked by a driver loop.

    Args:
        vehicle: the vehicle (``poll()``, ``state``; satisfies behaviors.ports.VehiclePort).
        lsm: the Landing Site Manager (its ``on_decision`` should log into ``log``).
        source: the perception source.
        tree: the mission tree, or None until :meth:`attach_tree` (a live flight builds it
            once the vehicle's home is known).
        log: the event log.
        now: the clock's now.
        perception_every: tree ticks between perception updates.
        low_altitude_every: tree ticks between perception updates while the range finder
            reads less than ``low_altitude`` m; default ``perception_every``.
        low_altitude: m AGL.
        truth: a callable returning the simulator's ground truth of this tick (its
            ``position``, ``battery_percent``, ``touchdown``, ``crashed`` and
            ``crash_reason``, e.g. :meth:`sitl.Sitl.tick_truth`), or None when flying live.
        lockstep: True to drain the LSM queue synchronously after each perception update.
        console: optional phase console.
        loss_wait: clock seconds the mission holds for a lost link (see
            :mod:`autonomy.runner.link`).
        descent_flow: the descent watch's camera
            (:class:`autonomy.perception.descent_flow.DescentFlow`), updated every
            ``descent_flow_every`` ticks before the tree ticks; None without the watch.
        collisions: judges the true position every tick
            (:class:`autonomy.runner.collisions.CollisionWatch`); None when flying live.
    """

    def __init__(
        self, *, vehicle: Any, lsm: LandingSiteManager, source: Any,
        tree: py_trees.trees.BehaviourTree | None, log: EventLog, now: Callable[[], float],
        perception_every: int, truth: Callable[[], Any] | None, lockstep: bool,
        console: PhaseConsole | None = None, low_altitude_every: int | None = None,
        low_altitude: float = 0.0, loss_wait: float = 30.0,
        descent_flow: Any = None, descent_flow_every: int = 1, collisions: Any = None,
    ) -> None:
        self.vehicle = vehicle
        self.lsm = lsm
        self.source = source
        self.tree: py_trees.trees.BehaviourTree | None = None
        self.log = log
        self.now = now
        self.perception_every = max(1, int(perception_every))
        self.low_altitude_every = max(1, int(low_altitude_every or perception_every))
        self.low_altitude = float(low_altitude)
        self.truth = truth
        self.lockstep = lockstep
        self.console = console
        self.descent_flow = descent_flow
        self.descent_flow_every = max(1, int(descent_flow_every))
        self.collisions = collisions
        self.trace = FlightTrace()
        self.ticks = 0
        self.phase: str | None = None
        self.touchdown: tuple[float, float, float] | None = None
        self.touchdown_time: float | None = None
        self.touchdown_speed: float | None = None
        self.home: Any = None  # autonomy.runner.home.HomeChoice of a live flight
        self.home_moves: list[Any] = []  # autonomy.vehicle.home.HomeMove, recorded so far
        self.fence_noted: dict[str, Any] | None = None  # the last geofence upload that ended
        self._fence_seen: Any = None  # its autonomy.vehicle.fence.FenceUpload
        self.link = LinkWatch(vehicle, log, loss_wait,
                              note=console.note if console is not None else None)
        self._airborne = False
        self._last_touchdown: Any = None
        self._truth: Any = None  # ground truth of this tick
        self._reader = py_trees.blackboard.Client(name="runner")
        for key in (bb.PHASE, bb.LANDING_SITE, bb.OUTCOME_HINT, bb.FAILURE_REASON,
                    bb.VERIFICATION_ATTEMPTS, bb.SEARCH_PATTERNS):
            self._reader.register_key(key=key, access=py_trees.common.Access.READ)
        if tree is not None:
            self.attach_tree(tree)

    def attach_tree(self, tree: py_trees.trees.BehaviourTree) -> None:
        """Fly with ``tree`` from now on (its status changes are logged)."""
        tree.add_post_tick_handler(TreeStatusRecorder(self.log))
        self.tree = tree

    def note(self, text: str, **fields: Any) -> None:
        """Log a ``flight`` note event and show it on the console."""
        self.log.add("flight", event="note", text=text, **fields)
        if self.console is not None:
            self.console.note(self.now(), text)

    def read(self, key: str, default: Any = None) -> Any:
        """A blackboard value, or ``default`` when it is not set."""
        try:
            return self._reader.get(key)
        except KeyError:
            return default

    @property
    def status(self) -> Status:
        return Status.INVALID if self.tree is None else self.tree.root.status

    @property
    def link_gave_up(self) -> str | None:
        """Why the flight ended on the link (lost too long, or never heard), or None."""
        return self.link.gave_up

    @property
    def done(self) -> bool:
        """The tree finished (landed and disarmed, or failed)."""
        return self.status in (Status.SUCCESS, Status.FAILURE)

    def crashed(self) -> tuple[bool, str | None]:
        """Whether the simulator flagged a crash, and why."""
        if self.truth is None:
            return False, None
        truth = self._truth if self._truth is not None else self.truth()
        if not getattr(truth, "crashed", False):
            return False, None
        return True, getattr(truth, "crash_reason", None) or "crash"

    def tick(self) -> None:
        """One tick after the clock advanced: poll, perceive, decide, record. While the link
        is lost nothing is perceived or decided (the mission holds)."""
        assert self.tree is not None, "attach_tree() first"
        now = self.now()
        self.vehicle.poll()
        state = self.vehicle.state
        link = self.link.update(now)
        if link in (Link.HOLDING, Link.GAVE_UP):
            self._record(now, state)
            return
        if link is Link.RESUMED:
            self._restart_running()
        if state.position is not None:
            self.lsm.set_drone_position(state.position)
        agl = state.rangefinder_agl
        low = agl is not None and agl < self.low_altitude
        if self.ticks % (self.low_altitude_every if low else self.perception_every) == 0:
            for obs in self.source.update(state, now):
                self.lsm.submit(obs)
            if self.lockstep:
                self.lsm.process_pending()
            for event in self.source.drain_events():
                self.log.add("perception", **event)
        flow = self.descent_flow
        if flow is not None and self.ticks % self.descent_flow_every == 0:
            flow.update(state, now)
            for event in flow.drain_events():
                self.log.add("perception", **event)
        self.tree.tick()
        self.ticks += 1
        self._record(now, state)

    def _restart_running(self) -> None:
        """Stop the running leaf so that it starts again on this tick and re-issues its
        command (the loss cancelled it; the autopilot may have drifted meanwhile)."""
        tip = self.tree.tip() if self.tree is not None else None
        if tip is not None and tip.status == Status.RUNNING:
            self.log.add("link", event="resume", behaviour=tip.name)
            tip.stop(Status.INVALID)

    def follow(self) -> Link:
        """Poll and record without ticking the tree (before the tree exists, or while the
        vehicle is flown by someone else, e.g. landing after Ctrl-C); returns the link's
        verdict for this tick."""
        now = self.now()
        self.vehicle.poll()
        link = self.link.update(now)
        self._record(now, self.vehicle.state)
        return link

    def _record(self, now: float, state: Any) -> None:
        moves = getattr(self.vehicle, "home_moves", ())
        if len(moves) > len(self.home_moves):
            self._note_home_moves(moves)
        fence = getattr(self.vehicle, "fence_upload", None)
        if fence is not None and fence is not self._fence_seen and fence.handle.status.done:
            self._fence_seen = fence
            self._note_fence(fence)
        truth = self._truth = self.truth() if self.truth is not None else None
        if truth is not None:
            p = truth.position
            xyz = (float(p[0]), float(p[1]), float(p[2]))
            battery = getattr(truth, "battery_percent", None)
            if battery is None:
                battery = state.battery_percent
        else:
            xyz = state.position
            battery = state.battery_percent
        self.trace.append(now, xyz, battery)
        if self.collisions is not None and truth is not None:
            self.collisions.update(now, xyz)
        self._track_touchdown(now, truth, state)
        if py_trees.blackboard.Blackboard.activity_stream is None:
            # What the client's get returns when nobody watches the blackboard, without its
            # access checks (the runner registered the key to read it at construction).
            phase = py_trees.blackboard.Blackboard.storage.get(bb.PHASE)
        else:
            phase = self.read(bb.PHASE)
        if phase != self.phase and phase is not None:
            self.phase = phase
            self.trace.phases.append((now, phase))
            best = self.lsm.best(state.position) if state.position is not None else None
            loss = None if best is None or math.isnan(best.loss) else best.loss
            self.log.add("phase", phase=phase, position=xyz, battery=battery,
                         sites=len(self.lsm), best_loss=loss)
            if self.console is not None:
                self.console.phase(now, phase, None if xyz is None else xyz[2],
                                   len(self.lsm), loss, battery)
        self.log.flush()  # this tick's events on disk (tail -f, a killed run)

    def _note_home_moves(self, moves: list[Any]) -> None:
        """Record the vehicle's new home moves (the flight keeps its frame; the user sees
        where home went)."""
        for move in moves[len(self.home_moves):]:
            self.home_moves.append(move)
            self.log.add("flight", event="home_moved", **move.as_dict())
            if self.console is not None:
                self.console.note(move.time, move.describe())

    def _note_fence(self, fence: Any) -> None:
        """Record how the geofence upload ended (autonomy.vehicle.fence.FenceUpload)."""
        self.fence_noted = fence.as_dict()
        event = "geofence_uploaded" if fence.uploaded else "geofence_refused"
        self.log.add("flight", event=event, **self.fence_noted)
        if self.console is not None:
            self.console.note(self.now(), fence.describe())

    def _track_touchdown(self, now: float, truth: Any, state: Any) -> None:
        if truth is not None:
            td = truth.touchdown  # sitl.Touchdown(x, y, z, speed) of the last touchdown
            if td is not None and td != self._last_touchdown:
                self._last_touchdown = td
                self._touch(now, (float(td.x), float(td.y), float(td.z)), float(td.speed))
            return
        # Live: the autopilot's landed state going from air to ground is the touchdown.
        if state.landed_state in (LandedState.IN_AIR, LandedState.LANDING):
            self._airborne = True
        elif state.landed_state == LandedState.ON_GROUND and self._airborne:
            self._airborne = False
            if state.position is not None:
                self._touch(now, tuple(state.position), abs(state.velocity[2]))

    def _touch(self, now: float, xyz: tuple[float, float, float], speed: float | None) -> None:
        self.touchdown, self.touchdown_time, self.touchdown_speed = xyz, now, speed
        self.log.add("flight", event="touchdown", position=xyz, speed=speed)


def restore_fence(flight: Flight, advance: Callable[[], None], budget: float = 60.0) -> None:
    """After the flight: put back the vehicle's own geofence (``Driver.restore_fence``) if
    the flight uploaded one, once the vehicle is disarmed; follow it at most ``budget`` clock
    seconds. Recorded as an event ``geofence_restored`` (or ``geofence_not_restored``), a
    console line and ``restored`` in the upload's record."""
    vehicle = flight.vehicle
    fence = getattr(vehicle, "fence_upload", None)
    if fence is None or not fence.uploaded or flight.link_gave_up is not None:
        return
    if vehicle.state.armed:
        text = ("geofence not restored on the autopilot: the vehicle is still armed; the "
                "mission's stays in force")
    else:
        handle = vehicle.restore_fence()
        end = flight.now() + budget
        while not handle.status.done and flight.now() < end:
            advance()
            if flight.follow() is Link.GAVE_UP:
                break
        text = fence.describe_restore()
    restored = fence.restore is not None and fence.restore.status is CommandStatus.ACCEPTED
    if flight.fence_noted is not None:
        flight.fence_noted["restored"] = text
    flight.log.add("flight", event="geofence_restored" if restored else "geofence_not_restored",
                   text=text)
    if flight.console is not None:
        flight.console.note(flight.now(), text)


def bring_down(flight: Flight, reason: str, action: str, advance: Callable[[], None],
               budget: float = 180.0) -> str:
    """The tree has stopped: land (or hold) the vehicle with a direct command and follow it
    until it is down and disarmed (or holding), at most ``budget`` clock seconds. A lost link
    is waited for as during the mission (the command is sent again when it is back), never
    flown over for the whole budget.

    Returns the stop reason, e.g. ``"mission failed (land: accepted)"``.
    """
    vehicle = flight.vehicle
    state = vehicle.state
    if action == "land" and not state.armed:
        return reason  # already down: nothing to do
    flight.log.add("flight", event=action, reason=reason)

    def command() -> Any:
        return vehicle.land() if action == "land" else vehicle.hold()

    handle = command()
    end = flight.now() + budget
    while flight.now() < end:
        advance()
        link = flight.follow()
        if link is Link.GAVE_UP:
            return f"{reason} ({action}: {flight.link_gave_up})"
        if link is Link.HOLDING:
            continue
        if link is Link.RESUMED:
            handle = command()
        state = vehicle.state
        if flight.crashed()[0]:
            break
        if action == "hold" and handle.status.done:
            break
        if (action == "land" and not state.armed
                and state.landed_state in (LandedState.ON_GROUND, LandedState.UNDEFINED)):
            break
    return f"{reason} ({action}: {handle.status.value})"
