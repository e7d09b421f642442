"""report.html for a flight that never wrote its report (the process was killed): rebuilt
from the logs it left, which are written as the flight goes.

events.jsonl (flushed every tick) gives the phases, the LSM's and the detector's events and the
touchdown; flight.tlog the track (the vehicle's LOCAL_POSITION_NED, converted to ENU as the
driver does) and the battery (SYS_STATUS); tree.btlog, read to its last whole transition, the
tree's timeline. What only the end of a flight knows (the retained sites and their losses,
the ground truth) is missing from such a page, and the page says the flight did not finish.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from autonomy.errors import UserError
from autonomy.report.data import FlightData, FlightTrace
from autonomy.report.html import write_flight_page
from autonomy.report.summary import build_summary
from autonomy.vehicle.tlog import SIM_EPOCH

UNFINISHED = "unfinished"
_GCS_SYSTEM = 255  # our own ground station's messages in the tlog are left out


def read_events_lenient(path: Path) -> list[dict[str, Any]]:
    """The events of an events.jsonl that may end inside a line (a killed flight)."""
    events = []
    with path.open(encoding="utf-8", errors="replace") as stream:
        for line in stream:
            try:
                event = json.loads(line)
            except json.JSONDecodeError:
                continue
            if isinstance(event, dict) and isinstance(event.get("t"), (int, float)):
                events.append(event)
    return events


def _tlog_trace(path: Path, first_event: float) -> FlightTrace | None:
    """The track and battery in a flight.tlog, on the flight clock, or None without any."""
    from pymavlink import mavutil

    trace = FlightTrace()
    battery: float | None = None
    offset: float | None = None
    try:
        log = mavutil.mavlink_connection(str(path), robust_parsing=True)
    except OSError:
        return None
    try:
        while True:
            msg = log.recv_match(type=["LOCAL_POSITION_NED", "SYS_STATUS"])
            if msg is None:
                break
            if msg.get_srcSystem() == _GCS_SYSTEM:
                continue
            stamp = float(getattr(msg, "_timestamp", 0.0))
            if offset is None:  # lockstep logs start at SIM_EPOCH; live ones at wall time
                offset = SIM_EPOCH if 0 <= stamp - SIM_EPOCH < 1e7 else stamp - first_event
            if msg.get_type() == "SYS_STATUS":
                battery = None if msg.battery_remaining < 0 else float(msg.battery_remaining)
                continue
            trace.append(stamp - offset, (float(msg.y), float(msg.x), -float(msg.z)), battery)
    except Exception:  # pymavlink on a cut or corrupt record: the track ends where it is
        pass
    finally:
        log.close()
    return trace if trace.t else None


def _phase_trace(events: list[dict[str, Any]]) -> FlightTrace:
    """A coarse track from the positions logged at each phase change."""
    trace = FlightTrace()
    for e in events:
        if e.get("kind") == "phase" and isinstance(e.get("position"), list):
            trace.append(e["t"], tuple(e["position"]), e.get("battery"))
    return trace


def rebuild_page(folder: Path) -> Path:
    """Write ``folder/report.html`` from the logs of an unfinished flight; raises
    :class:`UserError` when the folder has no events.jsonl to build it from."""
    folder = Path(folder)
    path = folder / "events.jsonl"
    if not path.is_file():
        raise UserError(f"{folder}: no report.html, and no events.jsonl to rebuild one from")
    events = read_events_lenient(path)
    if not events:
        raise UserError(f"{path}: no event in it: nothing to rebuild a page from")
    start = next((e for e in events if e.get("kind") == "flight" and e.get("event") == "start"),
                 {})
    trace = None
    if (folder / "flight.tlog").is_file():
        trace = _tlog_trace(folder / "flight.tlog", float(events[0]["t"]))
    trace = trace or _phase_trace(events)
    trace.phases = [(e["t"], e["phase"]) for e in events if e.get("kind") == "phase"]
    touchdown = next((e for e in reversed(events) if e.get("event") == "touchdown"), None)
    end = max([float(events[-1]["t"]), *(trace.t[-1:] or [])])
    hits = [{k: v for k, v in e.items() if k not in ("kind", "event")} for e in events
            if e.get("kind") == "flight" and e.get("event") == "collision"]
    reason = "unfinished: the flight stopped before writing its report; rebuilt from its logs"
    data = FlightData(
        mission_name=start.get("mission") or folder.name, seed=start.get("seed") or 0,
        autopilot="-", world="-", detector="-", trace=trace, end_time=end, status="RUNNING",
        stop_reason=reason, sites=[], ban_zones=[], chosen_site=None,
        touchdown=tuple(touchdown["position"]) if touchdown else None,
        touchdown_time=touchdown["t"] if touchdown else None,
        touchdown_speed=touchdown.get("speed") if touchdown else None, touchdown_safe=None,
        crashed=False, crash_reason=None, outcome_hint=None, failure_reason=None,
        verification_attempts=0, search_patterns=0, sites_verified=0, lsm_counters={},
        perception_counters={}, lockstep=bool(start.get("lockstep", True)),
        collisions=len(hits) if start.get("lockstep", True) else None,
        first_collision=hits[0] if hits else None,
    )
    summary = build_summary(data)
    summary.update(outcome=UNFINISHED, exit_code=None, exit_meaning=reason,
                   sites_retained="-", sites_verified="-", sites_banned=sum(
                       1 for e in events if e.get("decision") == "banned"))
    return write_flight_page(data, summary, events, folder)
