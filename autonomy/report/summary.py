"""The flight's outcome, its summary.json and the console's closing lines."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from autonomy.report.data import FlightData, zone_record
from autonomy.report.events import _clean
from behaviors.blackboard import FAILSAFE_KINDS

OUTCOMES = ("landed", "landed_unjudged", "landed_unsafe", "crashed", "no_site", "failsafe",
            "aborted", "link_lost", "refused")
"""landed: touched down and disarmed on a verified site (or, once the landing tries are
spent, on the best site verified earlier: outcome hint "verified_site"), on ground the
simulator's ground truth judged safe (lockstep flights); landed_unjudged: the same landing
with no ground truth to judge the ground by (live flights); landed_unsafe: touched down on
ground the truth calls unsafe; crashed: the simulator flagged a crash, or the rotors touched
raised ground or a moving obstacle (a collision); no_site: no landing
try was left (by count or by battery) and no verified site either: the vehicle landed in
place on purpose; failsafe: a failsafe (critical battery, GPS loss) took over and landed
wherever the vehicle was, on safe ground or not; aborted: the mission failed, hit the time
limit or was interrupted before landing; link_lost: the autopilot was not heard for longer
than the flight waits (or never heard): it is left to its own failsafe; refused: a live
flight refused to take off (the file's home and the vehicle's disagree)."""

EXIT_CODES = {"landed": 0, "refused": 2, "landed_unjudged": 3, "link_lost": 4}
"""``lander fly``'s exit code per outcome; any other outcome exits 1."""

EXIT_MEANINGS = {
    0: "landed on ground the simulator's ground truth judged safe (lockstep flights only)",
    1: "did not land as planned (landed_unsafe, crashed, no_site, failsafe or aborted)",
    2: "bad input, or refused before takeoff (the file's home and the vehicle's disagree)",
    3: "landed and disarmed on a verified site; the ground was not judged (live flight: no "
       "ground truth)",
    4: "link lost: the autopilot was not heard for longer than the flight waits, or never; "
       "it is left to its own failsafe",
}
"""What each exit code of ``lander fly`` means (also in ``lander fly --help`` and README)."""


def exit_code(outcome: str) -> int:
    """The exit code ``lander fly`` gives a flight with ``outcome``."""
    return EXIT_CODES.get(outcome, 1)

HINT_WORDS = {
    "no_site": "no landing try left; landed in place",
    "verified_site": "no landing try left; landed on the best site verified earlier",
    "battery_critical": "the battery reached the critical level; landed where it was",
    "gps_lost": "the 3D GPS fix was lost; landed where it was",
    "battery_reserve": "waypoints skipped at the battery reserve",
}
"""What each outcome hint (behaviors.blackboard.OUTCOME_HINT) means, for the console."""


def classify(data: FlightData) -> str:
    """The outcome (one of :data:`OUTCOMES`) of a finished flight."""
    if data.refused:
        return "refused"
    # A contact of the rotors with raised ground or a moving obstacle is a crash for a real
    # vehicle, though the simulated one flies on: judged as one.
    if data.crashed or data.collisions:
        return "crashed"
    if data.link_lost is not None:
        return "link_lost"
    if data.status != "SUCCESS":
        return "aborted"
    if data.outcome_hint in FAILSAFE_KINDS:
        return "failsafe"
    if data.outcome_hint == "no_site":
        return "no_site"
    if data.touchdown_safe is False:
        return "landed_unsafe"
    if data.touchdown_safe is None:
        return "landed_unjudged"
    return "landed"


def build_summary(data: FlightData) -> dict[str, Any]:
    """The summary.json dict of a flight (times in clock seconds, distances in metres)."""
    site = data.chosen_site
    error = None
    if site is not None and data.touchdown is not None:
        error = math.hypot(data.touchdown[0] - site.x, data.touchdown[1] - site.y)
    mission_end = data.trace.mission_end()
    time_to_land = None
    if mission_end is not None and data.touchdown_time is not None:
        time_to_land = max(0.0, data.touchdown_time - mission_end)
    _, _, battery = data.trace.arrays()
    known = battery[~np.isnan(battery)]
    start = float(known[0]) if known.size else None
    end = float(known[-1]) if known.size else None
    counters = dict(sorted(data.lsm_counters.items()))
    outcome = classify(data)
    summary = {
        "mission": data.mission_name,
        "seed": data.seed,
        "autopilot": data.autopilot,
        "world": data.world,
        "detector": data.detector,
        "mode": "lockstep" if data.lockstep else "live",
        "outcome": outcome,
        "exit_code": exit_code(outcome),
        "exit_meaning": EXIT_MEANINGS[exit_code(outcome)],
        "tree_status": data.status,
        "stop_reason": data.stop_reason,
        "outcome_hint": data.outcome_hint,
        "failure_reason": data.failure_reason,
        "crash_reason": data.crash_reason,
        "link_lost": data.link_lost,
        "interrupted": data.interrupted,
        "chosen_site": None if site is None else {
            "id": site.id, "x": site.x, "y": site.y, "z": site.z,
            "roughness": site.roughness, "uncertainty": site.uncertainty, "size": site.size,
            "verification_altitude": site.verification_altitude,
            "verified": data.chosen_verified,
        },
        "touchdown": None if data.touchdown is None else {
            "x": data.touchdown[0], "y": data.touchdown[1], "z": data.touchdown[2],
            "speed": data.touchdown_speed, "t": data.touchdown_time,
        },
        "touchdown_error": error,
        "touchdown_safe": data.touchdown_safe,
        "collisions": data.collisions,
        "first_collision": data.first_collision,
        "mission_time": data.end_time,
        "mission_end_time": mission_end,
        "time_to_land": time_to_land,
        "distance": data.trace.distance(),
        "energy": {
            "battery_start": start,
            "battery_end": end,
            "battery_used": None if start is None else start - end,
            "wh": data.energy_wh,
        },
        "sites_received": counters.get("received", 0),
        "sites_retained": len(data.sites),
        "sites_verified": data.sites_verified,
        "sites_banned": len(data.ban_zones),
        "verification_attempts": data.verification_attempts,
        "search_patterns": data.search_patterns,
        "lsm_counters": counters,
        "perception": dict(sorted(data.perception_counters.items())),
        "link": data.link,
        "home": data.home,
        "home_moves": data.home_moves,
        "wall_time": data.wall_time,
        "realtime_factor": (
            data.end_time / data.wall_time if data.lockstep and data.wall_time > 0 else None
        ),
    }
    if data.geofence is not None:  # only then: summaries of flights without one unchanged
        summary["geofence"] = [list(v) for v in data.geofence]
    if data.geofence_exclude:  # the no-fly zones, ENU m, when the mission has any
        summary["geofence_exclude"] = [zone_record(zone) for zone in data.geofence_exclude]
    if data.geofence_upload is not None:
        summary["geofence_upload"] = data.geofence_upload
    return _clean(summary)


def write_summary(summary: dict[str, Any], path: Path) -> None:
    path.write_text(json.dumps(summary, indent=2) + "\n", encoding="utf-8")


def format_summary(summary: dict[str, Any]) -> str:
    """A few human lines about a flight, for the end of the console output."""

    def num(value: Any, fmt: str = ".1f", unit: str = "") -> str:
        return "-" if value is None else f"{value:{fmt}}{unit}"

    hint = summary.get("outcome_hint")
    lines = [f"outcome: {summary['outcome']}"]
    if hint:
        lines[0] += f" ({hint}: {HINT_WORDS[hint]})" if hint in HINT_WORDS else f" ({hint})"
    if summary.get("failure_reason") and summary["outcome"] == "aborted":
        lines.append(f"reason: {summary['failure_reason']}")
    elif summary["outcome"] == "aborted":
        lines.append(f"reason: {summary['stop_reason']}")
    elif summary["outcome"] == "link_lost":
        lines.append(f"reason: {summary['link_lost']}")
    site = summary.get("chosen_site")
    td = summary.get("touchdown")
    if td is not None:
        safe = {True: "safe", False: "UNSAFE", None: "not judged"}[summary["touchdown_safe"]]
        where = f"touchdown at ({td['x']:.1f}, {td['y']:.1f}, {td['z']:.1f}) m, ground {safe}"
        if site is not None:
            where += (f"; {num(summary['touchdown_error'], '.2f', ' m')} from site "
                      f"{site['id']}")
        lines.append(where)
    if summary.get("collisions"):
        first = summary["first_collision"]
        lines.append(f"COLLISIONS: {summary['collisions']}, the first with the "
                     f"{first['obstacle']} at {first['t']:.1f} s")
    for move in summary.get("home_moves") or ():
        lines.append(move["text"])
    if summary.get("geofence_upload"):
        lines.append(summary["geofence_upload"]["text"])
        if summary["geofence_upload"].get("restored"):
            lines.append(summary["geofence_upload"]["restored"])
    energy = summary["energy"]
    lines.append(
        f"mission time {num(summary['mission_time'], '.1f', ' s')}, time to land "
        f"{num(summary['time_to_land'], '.1f', ' s')}, distance "
        f"{num(summary['distance'], '.0f', ' m')}, battery used "
        f"{num(energy['battery_used'], '.1f', ' %')}"
    )
    lines.append(
        f"sites: {summary['sites_received']} observations, {summary['sites_retained']} "
        f"retained, {summary['sites_verified']} verified, {summary['sites_banned']} banned; "
        f"{summary['verification_attempts']} verification attempts, "
        f"{summary['search_patterns']} search patterns"
    )
    link = summary.get("link")
    if link and (link["losses"] or summary["mode"] == "live"):
        lines.append(
            f"link: {link['messages_received']} messages, {link['corrupt_packets']} corrupt, "
            f"{link['bad_signature']} bad signatures, {link['backlog_dropped_bytes']} bytes "
            f"dropped; lost {link['losses']} time(s) for {link['time_lost']:.1f} s, longest "
            f"heartbeat gap {link['longest_heartbeat_gap']:.1f} s"
        )
    if summary.get("realtime_factor"):
        lines.append(
            f"simulated {summary['mission_time']:.0f} s in {summary['wall_time']:.1f} s "
            f"({summary['realtime_factor']:.0f}x real time)"
        )
    if "exit_code" in summary:
        lines.append(f"exit {summary['exit_code']}: {summary['exit_meaning']}")
    return "\n".join(lines)
