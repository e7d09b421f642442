"""fly(): one mission, lockstep against the embedded SITL or live over a MAVLink link.

Lockstep (``sim://``): every tick advances the simulator and a :class:`SimClock` by
``1 / tick_rate`` and then runs the tick, so a flight takes only CPU time and two flights
with the same seed are identical. Live (any other connection, :mod:`autonomy.runner.live`):
the LSM runs on its worker thread, the clock follows the vehicle's own time, the tree ticks
at ``tick_rate`` in that time once the vehicle's home is known, and Ctrl-C lands (or holds)
the vehicle before returning. The report files are written whatever ends the flight.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import py_trees

from autonomy.clock import SimClock, VehicleClock
from autonomy.config import MAX_SEED, Mission
from autonomy.errors import UserError, one_line
from autonomy.report import (
    EventLog,
    FlightData,
    build_summary,
    format_summary,
    write_flight_page,
    write_report_png,
    write_summary,
)
from autonomy.runner.flight import Flight, PhaseConsole, bring_down, restore_fence
from autonomy.runner.home import HomeMismatch
from autonomy.runner.interrupt import ctrl_c_flag
from autonomy.runner.progress import FlightProgress
from autonomy.runner.world import (
    FlightSeeds,
    build_collision_watch,
    build_descent_flow,
    build_sitl,
    build_source,
    build_terrain,
    judge_touchdown,
)
from behaviors import blackboard as bb
from behaviors.settings import MissionPlan
from lsm import LandingSiteManager

Status = py_trees.common.Status
REPORT_FILES = ("summary.json", "events.jsonl", "flight.tlog", "report.png", "report.html")


@dataclass
class FlightResult:
    """What :func:`fly` returns.

    Attributes:
        summary: the summary.json dict (see :func:`autonomy.report.build_summary`).
        events: every event of the flight, as written to events.jsonl.
        data: the trace and end state the report was drawn from.
        out_dir: where the report files are, or None when none were written.
    """

    summary: dict[str, Any]
    events: list[dict[str, Any]] = field(repr=False)
    data: FlightData = field(repr=False)
    out_dir: Path | None = None

    @property
    def outcome(self) -> str:
        return self.summary["outcome"]

    @property
    def exit_code(self) -> int:
        """The exit code ``lander fly`` gives this flight (see README "Exit codes")."""
        return self.summary["exit_code"]


def _projection(sitl: Any):
    """The lat/lon projection of the embedded SITL's personality (``project`` of
    :meth:`Mission.plan`)."""
    from autonomy.vehicle.frames import geodetic_to_local

    autopilot = sitl.personality if sitl is not None else "ardupilot"

    def project(lat: float, lon: float, lat0: float, lon0: float) -> tuple[float, float]:
        return geodetic_to_local(lat, lon, lat0, lon0, autopilot)

    return project


def fly(
    mission: Mission,
    *,
    seed: int | None = None,
    out_dir: Path | str | None = None,
    console: bool = False,
    on_interrupt: Literal["land", "hold"] = "land",
    progress: FlightProgress | bool | None = None,
    report_png: bool = True,
) -> FlightResult:
    """Fly ``mission`` and report on it.

    Args:
        mission: the validated mission.
        seed: overrides ``mission.seed`` (terrain, sensor noise, wind, pattern centres),
            0 .. 2**32-1.
        out_dir: directory for summary.json, events.jsonl, flight.tlog, report.png and
            report.html (created); None writes nothing, which is fastest. They are written
            whatever ends the flight once it started: landing, failure, Ctrl-C (summary
            ``interrupted``: true) or an internal error (raised again afterwards). Once the tree is
            built, tree.btlog (its transitions, for Groot2: :mod:`behaviors.btlog`) and
            blackboard.jsonl (:mod:`behaviors.bblog`) are written beside them as it ticks.
        console: print a line per phase change, link and home notes, and a closing summary
            to stdout.
        on_interrupt: live mode only: what Ctrl-C does before returning. A lockstep flight
            stops where it is on Ctrl-C (it is simulated: nothing needs bringing down).
        progress: lockstep only: a :class:`FlightProgress` line on stderr; True for the
            default one, None for one when ``console`` is set.
        report_png: with ``out_dir``, draw report.png too (report.html, the page to
            inspect the flight in a browser, is always written there).

    Raises:
        HomeMismatch: live only: the file's home and the vehicle's disagree and
            ``vehicle.home_from`` does not say which to fly by; raised after the report files
            are written (``exc.result`` is the FlightResult, outcome ``refused``).
        UserError: a seed out of range, the vehicle cannot be reached, or the world cannot
            be built.
    """
    from autonomy.runner.services import build_services
    from autonomy.vehicle import connect
    from behaviors.recording import TreeRecorder
    from behaviors.tree import build_mission_tree

    seed = mission.seed if seed is None else seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not (
        0 <= seed <= MAX_SEED
    ):
        raise UserError(f"seed: must be an integer 0 .. 2**32-1, got {seed!r}")
    seed = int(seed)
    seeds = FlightSeeds.derive(seed)
    lockstep = mission.vehicle.lockstep
    out = Path(out_dir) if out_dir is not None else None
    if out is not None:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(f"{out}: cannot create the report directory "
                            f"({exc.strerror or exc})") from None
    wall_start = time.perf_counter()
    bb.reset()  # nothing of an earlier flight in this process may be read as this one's

    if progress is None:
        progress = console and lockstep
    meter = None
    if progress is True:
        meter = FlightProgress(mission.name or "mission", mission.time_limit,
                               len(mission.waypoints))
    elif isinstance(progress, FlightProgress):
        meter = progress
    terrain = build_terrain(mission, seeds.terrain)
    clock: Any = SimClock() if lockstep else VehicleClock()
    log = EventLog(clock.now, out / "events.jsonl" if out else None)
    lsm = LandingSiteManager(
        mission.lsm, mission.weights,
        on_decision=lambda d: log.add("lsm", decision=d.kind, site=d.site_id,
                                      reason=d.reason),
    )
    source = build_source(mission, terrain, np.random.default_rng(seeds.perception))
    sitl = build_sitl(mission, terrain, seeds.sitl) if lockstep else None
    descent_flow = build_descent_flow(mission, terrain, seeds.descent_flow)
    services = build_services(mission, source, obstacle_watch=descent_flow)
    vehicle = None
    refusal: HomeMismatch | None = None
    failure: BaseException | None = None
    data: FlightData | None = None
    recorders: list[TreeRecorder] = []  # tree.btlog and blackboard.jsonl, when out is set
    try:
        vehicle = connect(
            mission.vehicle.connection, clock, sitl=sitl,
            signing_key=mission.vehicle.signing_key_bytes(),
            link_timeout=mission.vehicle.link.link_timeout,
            settings=mission.vehicle.link,
            tlog_path=out / "flight.tlog" if out else None,
        )

        def build_tree(plan: MissionPlan) -> py_trees.trees.BehaviourTree:
            bb.reset()
            lsm.set_area(plan.geofence)  # about the home the plan was converted about
            tree = build_mission_tree(
                plan, vehicle, lsm, clock, np.random.default_rng(seeds.tree), mission.tree,
                services=services,
            )
            tree.setup()
            if out is not None:
                recorders.append(TreeRecorder(tree, out, clock.now))
            return tree

        flight = Flight(
            vehicle=vehicle, lsm=lsm, source=source, tree=None, log=log, now=clock.now,
            perception_every=_ticks_per_update(mission.tick_rate, mission.perception.rate),
            low_altitude_every=_ticks_per_update(
                mission.tick_rate,
                mission.perception.low_altitude_rate or mission.perception.rate,
            ),
            low_altitude=mission.perception.low_altitude,
            truth=sitl.tick_truth if sitl is not None else None,
            lockstep=lockstep,
            console=PhaseConsole(before_line=meter.clear if meter else None) if console else None,
            loss_wait=mission.vehicle.link.loss_wait,
            descent_flow=descent_flow,
            descent_flow_every=_ticks_per_update(
                mission.tick_rate, mission.perception.descent_flow.rate
            ),
            collisions=build_collision_watch(terrain, log) if sitl is not None else None,
        )
        try:
            if lockstep:
                # Lat/lon waypoints and geofence vertices as the simulated autopilot projects
                # them, as a live flight converts them (and as the geofence upload sends
                # them back), not on the tangent plane: 0.1-0.2 % of the distance apart.
                flight.attach_tree(build_tree(mission.plan(project=_projection(sitl))))
                vehicle.keep_frame()  # about the SITL's home (docs/how-to/live-flights.md)
            log.add("flight", event="start", mission=mission.name, seed=seed,
                    connection=mission.vehicle.connection, lockstep=lockstep)
            if lockstep:
                stop_reason = _run_lockstep(flight, sitl, clock, mission, meter)
            else:
                from autonomy.runner.live import run_live

                try:
                    stop_reason = run_live(flight, mission, clock, build_tree, on_interrupt)
                except HomeMismatch as exc:
                    refusal = exc
                    stop_reason = f"refused: {exc}"
        except Exception as exc:  # a bug: still write what the flight did, then raise it
            failure = exc
            stop_reason = f"internal error: {type(exc).__name__}: {one_line(str(exc))}"
        finally:
            if meter is not None:
                meter.clear()
        log.add("flight", event="end", status=flight.status.name, reason=stop_reason)
        try:
            data = _flight_data(mission, seed, flight, terrain, stop_reason, lockstep, sitl)
        except Exception:
            if failure is None:
                raise
            raise failure from None  # the first error is the one to see
        data.refused = refusal is not None
        data.interrupted = stop_reason.startswith("interrupted")
    finally:
        for recorder in recorders:
            recorder.close()
        if not lockstep:
            lsm.stop()
        if vehicle is not None:
            vehicle.close()
        if sitl is not None and hasattr(sitl, "close"):
            sitl.close()
        log.close()
    data.wall_time = time.perf_counter() - wall_start
    summary = build_summary(data)
    if out is not None:
        try:
            write_summary(summary, out / "summary.json")
            if report_png:  # matplotlib: ~20x the time of report.html (a campaign skips it)
                write_report_png(data, out / "report.png", outcome=summary["outcome"])
            write_flight_page(data, summary, log.events, out)
        except OSError as exc:
            if failure is not None:
                raise failure from None
            raise UserError(f"{out}: cannot write the report ({exc.strerror or exc})") from None
    if failure is not None:
        raise failure
    result = FlightResult(summary=summary, events=log.events, data=data, out_dir=out)
    if refusal is not None:
        refusal.result = result
        raise refusal  # one clear line from the CLI (exit 2); the report is written
    if console:
        print(format_summary(summary))
        if out is not None:
            print(f"report: {out / 'report.png'} (summary.json, events.jsonl, flight.tlog "
                  f"in {out})")
            print(f"inspect in a browser: {out / 'report.html'} (lander replay {out})")
    return result


def _ticks_per_update(tick_rate: float, rate: float) -> int:
    """Tree ticks between perception updates at ``rate`` Hz (at least one)."""
    return max(1, round(tick_rate / rate))


def _run_lockstep(flight: Flight, sitl: Any, clock: SimClock, mission: Mission,
                  meter: FlightProgress | None = None) -> str:
    """Tick until the flight ends; Ctrl-C stops it where it is (``"interrupted"``: the
    simulation just stops, the report is written)."""
    dt = 1.0 / mission.tick_rate

    def advance() -> None:
        if interrupted.is_set():
            raise _Interrupted
        sitl.step(dt)
        clock.advance(dt)
        if meter is not None and meter.due():
            tip = flight.tree.tip() if flight.tree is not None else None
            meter.show(clock.now(), flight.phase, None if tip is None else tip.name)

    def ticks() -> str:
        for _ in range(math.ceil(mission.time_limit * mission.tick_rate)):
            advance()
            flight.tick()
            if flight.crashed()[0]:
                return "crashed"
            if flight.link_gave_up is not None:
                return f"link lost: {flight.link_gave_up}"
            status = flight.status
            if status == Status.SUCCESS:
                return "landed"
            if status == Status.FAILURE:
                return bring_down(flight, "mission failed", "land", advance)
        return bring_down(flight, "time limit", "land", advance)

    with ctrl_c_flag() as interrupted:
        try:
            reason = ticks()
            if mission.geofence is not None and mission.geofence.restore:
                restore_fence(flight, advance)
            return reason
        except (_Interrupted, KeyboardInterrupt):
            flight.note(f"interrupted (Ctrl-C) at {clock.now():.1f} s simulated; the "
                        "simulation stops here")
            return "interrupted (Ctrl-C)"


class _Interrupted(Exception):
    """Ctrl-C was pressed during a lockstep flight."""


def _flight_data(mission: Mission, seed: int, flight: Flight, terrain: Any,
                 stop_reason: str, lockstep: bool, sitl: Any) -> FlightData:
    lsm = flight.lsm
    sites = list(lsm.ranked(flight.vehicle.state.position))
    crashed, crash_reason = flight.crashed()
    if not crashed and flight.collisions is not None and flight.collisions.first is not None:
        first = flight.collisions.first
        crash_reason = f"collision with the {first['obstacle']} at {first['t']:.1f} s"
    touchdown = flight.touchdown
    safe = None
    if touchdown is not None and lockstep:
        safe = judge_touchdown(terrain, touchdown[0], touchdown[1], flight.touchdown_time)
    chosen = flight.read(bb.LANDING_SITE)
    energy = None
    _, _, battery = flight.trace.arrays()
    known = battery[~np.isnan(battery)]
    if lockstep and known.size and hasattr(mission.sitl, "battery"):
        pack = mission.sitl.battery
        energy = (known[0] - known[-1]) / 100 * pack.capacity_mah / 1000 * pack.cells * 3.7
    return FlightData(
        mission_name=mission.name,
        seed=seed,
        autopilot=getattr(flight.vehicle.state, "autopilot", mission.vehicle.autopilot),
        world=getattr(terrain, "kind", "flat"),
        detector=mission.perception.detector,
        trace=flight.trace,
        end_time=flight.now(),
        status=flight.status.name,
        stop_reason=stop_reason,
        sites=sites,
        ban_zones=list(lsm.ban_zones()),
        lockstep=lockstep,
        chosen_site=chosen,
        chosen_verified=None if chosen is None else bool(lsm.is_verified(chosen)),
        touchdown=touchdown,
        touchdown_time=flight.touchdown_time,
        touchdown_speed=flight.touchdown_speed,
        touchdown_safe=safe,
        crashed=crashed,
        crash_reason=crash_reason,
        outcome_hint=flight.read(bb.OUTCOME_HINT),
        failure_reason=flight.read(bb.FAILURE_REASON),
        verification_attempts=int(flight.read(bb.VERIFICATION_ATTEMPTS, 0) or 0),
        search_patterns=int(flight.read(bb.SEARCH_PATTERNS, 0) or 0),
        sites_verified=sum(1 for s in sites if lsm.is_verified(s)),
        verified_ids=[s.id for s in sites if lsm.is_verified(s)],
        weights=mission.weights,
        lsm_counters=dict(lsm.counters()),
        perception_counters=dict(getattr(flight.source, "counters", dict)()),
        energy_wh=energy,
        terrain=terrain,
        link=_link_stats(flight.vehicle),
        link_lost=flight.link_gave_up,
        home=None if flight.home is None else flight.home.as_dict(),
        home_moves=[move.as_dict() for move in flight.home_moves] or None,
        collisions=None if flight.collisions is None else flight.collisions.count,
        first_collision=None if flight.collisions is None else flight.collisions.first,
        geofence=None if lsm.area is None else list(lsm.area.vertices),
        geofence_exclude=[] if lsm.area is None else list(lsm.area.exclusions),
        geofence_upload=flight.fence_noted,
    )


def _link_stats(vehicle: Any) -> dict[str, Any]:
    """The driver's link statistics for summary.json (times in clock seconds)."""
    s = vehicle.stats
    return {
        "messages_received": s.messages, "bytes_received": s.bytes_received,
        "messages_sent": s.messages_sent, "corrupt_packets": s.corrupt_packets,
        "corrupt_bytes": s.corrupt_bytes, "bad_signature": s.bad_signature,
        "backlog_dropped_bytes": s.backlog_dropped_bytes, "ignored": s.ignored,
        "read_errors": s.read_errors, "write_errors": s.write_errors,
        "heartbeats": s.heartbeats, "first_heartbeat": s.first_heartbeat,
        "longest_heartbeat_gap": vehicle.longest_heartbeat_gap(),
        "losses": s.links_lost, "time_lost": vehicle.time_lost(),
    }


__all__ = ["REPORT_FILES", "FlightResult", "fly"]
