"""Flying one campaign run in whatever process a backend chose, and recording it.

:func:`fly_run` is a top-level function so that spawned pool workers and Dask workers can
unpickle it; it never raises for a failing flight: the run is recorded as ``error`` with its
traceback instead.
"""

from __future__ import annotations

import math
import os
import socket
import threading
import time
import traceback
from collections.abc import Mapping
from typing import Any

from autonomy.campaign.plan import RunTask

#: Flight summary fields copied into every run record (``None`` when a flight lacks one).
SUMMARY_FIELDS: tuple[str, ...] = (
    "outcome",
    "outcome_hint",  # why the landing phase ended (no_site, battery_critical, gps_lost, ...)
    "touchdown_safe",
    "collisions",  # contacts with raised ground or moving obstacles (sitl.terrain.contact)
    "time_to_land",
    "distance",
    "energy",
    "sites_received",
    "sites_verified",
    "sites_banned",
    "verification_attempts",
    "search_patterns",
    "mission_time",
    "sites_retained",
    "touchdown_error",
    "stop_reason",
    "failure_reason",
    "crash_reason",
)
#: Record fields that are not the same when a run is repeated (left out of comparisons).
NONDETERMINISTIC_FIELDS: frozenset[str] = frozenset({"wall_time", "worker"})

# The flight stack keeps process-wide state (py_trees' blackboard), so a worker process with
# several threads (a Dask worker with --nthreads > 1) flies one run at a time.
_ONE_FLIGHT_AT_A_TIME = threading.Lock()


def _jsonable(value: Any) -> Any:
    """Plain JSON value of a summary field (numpy scalars and arrays included)."""
    if hasattr(value, "tolist"):
        value = value.tolist()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if value is None or isinstance(value, (bool, int, float, str)):
        return value
    return str(value)


def base_record(task: RunTask) -> dict[str, Any]:
    """Fields of a run record that come from its task."""
    return {
        "run_id": task.run_id,
        "mission": task.mission_id,
        "variant": task.variant,
        "variant_key": task.variant_key,
        "variant_label": task.variant_label,
        "values": _jsonable(task.values),
        "seed_index": task.seed_index,
        "seed": task.seed,
        "worker": f"{socket.gethostname()}:{os.getpid()}",
    }


def error_record(task: RunTask, message: str, wall_time: float | None = None,
                 worker_died: str | None = None) -> dict[str, Any]:
    """Record of a run that raised or whose worker died; ``message`` is the traceback or
    how the worker died. ``worker_died`` (e.g. ``"SIGKILL"``) marks a run whose worker
    process died under it: re-running the campaign flies it again."""
    record = base_record(task)
    record.update({field: None for field in SUMMARY_FIELDS})
    record.update({"outcome": "error", "battery_used": None, "touchdown": None,
                   "error": message})
    if worker_died is not None:
        record["worker_died"] = worker_died
    record["wall_time"] = wall_time
    return record


def _touchdown(value: Any) -> list[float] | None:
    """[x, y] ENU metres of the summary's touchdown ({"x", "y", ...} or a sequence)."""
    if isinstance(value, Mapping):
        value = [value.get("x"), value.get("y")]
    value = _jsonable(value)
    if isinstance(value, list) and len(value) >= 2 and None not in value[:2]:
        return [float(v) for v in value[:2]]
    return None


def summary_record(task: RunTask, summary: Mapping[str, Any], wall_time: float) -> dict:
    """Record of a finished flight from its summary dict (:func:`autonomy.runner.fly`'s
    ``summary``): ``energy`` is in Wh and ``battery_used`` in percent of the pack."""
    record = base_record(task)
    for field in SUMMARY_FIELDS:
        record[field] = _jsonable(summary.get(field))
    energy = summary.get("energy")
    record["battery_used"] = None
    if isinstance(energy, Mapping):
        record["energy"] = _jsonable(energy.get("wh"))
        record["battery_used"] = _jsonable(energy.get("battery_used"))
    record["touchdown"] = _touchdown(summary.get("touchdown"))
    record["error"] = None
    record["wall_time"] = wall_time
    return record


def fly_with_page(mission: Any, seed: int, out_dir: Any = None) -> Any:
    """:func:`autonomy.runner.fly` as a campaign flies it: the report files and report.html
    in ``out_dir`` when given, without report.png (its page shows the same, 20 times
    cheaper to write)."""
    from autonomy.runner import fly

    return fly(mission, seed=seed, out_dir=out_dir, report_png=False)


_flying = False  # True while fly_run runs in this process


def flying() -> bool:
    """Whether this process is flying a run: a local pool's worker takes Ctrl-C as the end of
    the run then, and leaves it to lander between runs (``autonomy.campaign._quiet_ctrl_c``)."""
    return _flying


def fly_run(task: RunTask) -> dict[str, Any]:
    """Fly one task and return its run record (an ``error`` record if the flight raised)."""
    global _flying
    with _ONE_FLIGHT_AT_A_TIME:
        _flying = True
        try:
            return _fly(task)
        finally:
            _flying = False


def fly_alone(task: RunTask, results: Any) -> None:
    """Fly one task in a process of its own and send ``("record", record)`` through the
    ``results`` connection, or ``("interrupted", None)`` when Ctrl-C stopped the run."""
    try:
        outcome = ("record", fly_run(task))
    except KeyboardInterrupt:
        outcome = ("interrupted", None)
    results.send(outcome)
    results.close()


def _fly(task: RunTask) -> dict[str, Any]:
    """The record of one run, flown here; an ``error`` record if the flight raised."""
    start = time.perf_counter()
    try:
        result = task.flight(task.mission, seed=task.seed, out_dir=task.out_dir)
        summary = getattr(result, "summary", result)
        if not isinstance(summary, Mapping) or "outcome" not in summary:
            raise TypeError(f"the flight returned no summary with an outcome: {result!r}")
        if summary.get("interrupted"):
            # Ctrl-C stopped the flight (it wrote its partial report): record nothing,
            # so that re-running the campaign flies this run again.
            raise KeyboardInterrupt
        return summary_record(task, summary, time.perf_counter() - start)
    except Exception:
        return error_record(task, traceback.format_exc(), time.perf_counter() - start)
