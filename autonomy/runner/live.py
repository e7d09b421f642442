"""A live flight: over a real MAVLink link, paced in the vehicle's own time.

Before the tree is built the runner waits for the autopilot's first HEARTBEAT (at most
``vehicle.link.connect_timeout``; outcome ``link_lost`` if none comes) and for its home
position (at most ``landing.preflight_timeout``), then chooses the home the lat/lon
waypoints are converted about (:mod:`autonomy.runner.home`; a disagreement refuses the
flight) and checks the mission about it with the rules the file was checked with about its
own home (a lat/lon geofence stays on the Earth while ENU waypoints move with the home). The
tree then ticks at ``tick_rate`` Hz of the :class:`~autonomy.clock.VehicleClock`:
the loop sleeps ``period / rate`` wall seconds, so against a SITL at 8x it ticks eight times
as often in wall time and every hover, timeout and perception rate stays in vehicle seconds.
Ctrl-C lands (or holds) the vehicle before returning.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import py_trees
from pydantic import ValidationError

from autonomy.clock import VehicleClock
from autonomy.config import Mission
from autonomy.runner.flight import Flight, bring_down, restore_fence
from autonomy.runner.home import HomeMismatch, choose_home
from autonomy.runner.interrupt import ctrl_c_flag
from autonomy.runner.link import Link
from autonomy.vehicle.frames import geodetic_to_local
from behaviors.settings import MissionPlan

Status = py_trees.common.Status
_MAX_SLEEP = 0.25  # wall s: a pause stays responsive to Ctrl-C and to a changed rate


def run_live(
    flight: Flight,
    mission: Mission,
    clock: VehicleClock,
    build_tree: Callable[[MissionPlan], py_trees.trees.BehaviourTree],
    on_interrupt: str = "land",
) -> str:
    """Fly ``mission`` live; returns the stop reason. ``build_tree(plan)`` makes the tree
    once the home is chosen.

    Raises:
        autonomy.runner.home.HomeMismatch: the file's home and the vehicle's disagree and
            ``vehicle.home_from`` does not say which to fly by, or the mission about the
            home flown by breaks a rule the file keeps about its own (a waypoint outside the
            geofence, off the elevation model, ...: :meth:`Mission.check_geometry`).
    """
    period = 1.0 / mission.tick_rate

    def pause() -> None:
        time.sleep(min(clock.wall_seconds(period), _MAX_SLEEP))

    flight.lsm.start()
    with ctrl_c_flag() as interrupted:
        try:
            waited = _await_vehicle(flight, mission, pause, interrupted)
            if waited is not None:
                return waited
            choice = choose_home(mission, flight.vehicle.state.home)
            # The flight's frame from here on: about the home just compared and converted
            # about; a later home (arming, DO_SET_HOME) is recorded, not followed.
            flight.vehicle.keep_frame()
            flight.home = choice
            flight.note(choice.describe(), home=choice.as_dict())
            autopilot = flight.vehicle.state.autopilot

            def project(lat: float, lon: float, lat0: float, lon0: float) -> tuple[float, float]:
                return geodetic_to_local(lat, lon, lat0, lon0, autopilot)

            try:  # checked with the file's rules again, about this home
                plan = mission.plan(home=choice.lat_lon, project=project)
            except ValueError as exc:  # e.g. ENU waypoints moved out of a lat/lon fence
                raise HomeMismatch(f"about {choice.whose_home()} {choice.lat_lon[0]:.6f}, "
                                   f"{choice.lat_lon[1]:.6f}: {_reason(exc)}") from None
            flight.attach_tree(build_tree(plan))
            reason = _fly(flight, mission, clock, pause, interrupted, on_interrupt)
            if mission.geofence is not None and mission.geofence.restore:
                restore_fence(flight, pause)
            return reason
        except KeyboardInterrupt:
            return "interrupted twice"


def _fly(flight: Flight, mission: Mission, clock: VehicleClock, pause: Callable[[], None],
         interrupted: threading.Event, on_interrupt: str) -> str:
    """Tick the tree at the mission's rate until the flight ends; returns the stop reason."""
    period = 1.0 / mission.tick_rate
    start = clock.now()
    next_tick = start
    while not interrupted.is_set():
        flight.tick()
        if flight.link_gave_up is not None:
            return f"link lost: {flight.link_gave_up}"
        if flight.status == Status.SUCCESS:
            return "landed"
        if flight.status == Status.FAILURE:
            return bring_down(flight, "mission failed", "land", pause)
        if clock.now() - start >= mission.time_limit:
            return bring_down(flight, "time limit", "land", pause)
        next_tick = max(next_tick + period, clock.now() - period)  # no burst after a lag
        time.sleep(min(clock.wall_seconds(next_tick - clock.now()), _MAX_SLEEP))
    print(f"interrupted: {'landing' if on_interrupt == 'land' else 'holding'} "
          "(Ctrl-C again to leave at once)", flush=True)
    return bring_down(flight, "interrupted", on_interrupt, pause)


def _await_vehicle(flight: Flight, mission: Mission, pause: Callable[[], None],
                   interrupted: threading.Event) -> str | None:
    """Wait for the first HEARTBEAT, then for the vehicle's home; None when both came,
    else the stop reason."""
    vehicle = flight.vehicle
    url = mission.vehicle.connection
    connect_timeout = mission.vehicle.link.connect_timeout
    flight.note(f"waiting for a heartbeat on {url} (up to {connect_timeout:g} s)")
    deadline = flight.now() + connect_timeout
    while vehicle.stats.first_heartbeat is None:
        if interrupted.is_set():
            return "interrupted before the vehicle was heard"
        if flight.now() >= deadline:
            flight.link.never_heard(flight.now(), url, connect_timeout)
            return f"link lost: {flight.link_gave_up}"
        pause()
        flight.follow()
    home_timeout = mission.landing.preflight_timeout
    flight.note(f"heard {vehicle.state.autopilot} (system {vehicle.target_system}); waiting "
                f"for its home position (up to {home_timeout:g} s)")
    deadline = flight.now() + home_timeout
    while vehicle.state.home is None:
        if interrupted.is_set():
            return "interrupted before the vehicle reported its home"
        if flight.now() >= deadline:
            reason = f"no home position (HOME_POSITION) from the vehicle within {home_timeout:g} s"
            flight.note(reason)
            return reason
        pause()
        if flight.follow() is Link.GAVE_UP:
            return f"link lost: {flight.link_gave_up}"
    return None


def _reason(exc: ValueError) -> str:
    """A plan's refusal as one line: a validator's message without pydantic's wrapping."""
    if isinstance(exc, ValidationError):
        return exc.errors()[0]["msg"].removeprefix("Value error, ")
    return str(exc)
