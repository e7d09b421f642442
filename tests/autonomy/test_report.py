"""The flight report pieces: event log, tree recorder, outcome, summary, plot."""

from __future__ import annotations

import json
import math

import py_trees

from autonomy.report import (
    EventLog,
    FlightData,
    FlightTrace,
    TreeStatusRecorder,
    build_summary,
    classify,
    exit_code,
    format_summary,
    read_events,
    write_report_png,
)
from lsm.records import LandingSite


def test_event_log_streams_json_lines_stamped_with_the_clock(tmp_path):
    now = [0.0]
    log = EventLog(lambda: now[0], tmp_path / "events.jsonl")
    log.add("flight", event="start", value=float("nan"), where=(1.23456789, 2))
    now[0] = 1.5
    log.add("lsm", decision="inserted", site=3)
    log.close()
    events = read_events(tmp_path / "events.jsonl")
    assert events == log.events
    assert events[0] == {"t": 0.0, "kind": "flight", "event": "start", "value": None,
                         "where": [1.2346, 2]}
    assert events[1]["t"] == 1.5


def test_event_log_writes_its_events_at_each_flush_and_close(tmp_path):
    # The runner flushes after every tick: a tick's events are then on disk (tail -f, a
    # killed run), without a write to the file per event.
    log = EventLog(lambda: 0.0, tmp_path / "events.jsonl")
    log.add("lsm", decision="inserted", site=1)
    log.add("lsm", decision="merged", site=1)
    log.flush()
    assert read_events(tmp_path / "events.jsonl") == log.events
    log.add("flight", event="end")
    log.close()
    assert read_events(tmp_path / "events.jsonl") == log.events


def _reference_clean(value):
    """The event log's cleaning as first written: one isinstance chain for every value."""
    import numpy as np

    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return round(value, 4) if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): _reference_clean(v) for k, v in value.items()}
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_reference_clean(v) for v in value]
    if value is None or isinstance(value, str):
        return value
    return str(value)


def test_events_are_cleaned_as_by_the_plain_isinstance_chain(tmp_path):
    """The log's type-first fast path gives what the plain chain gives, for plain values,
    numpy scalars and arrays, bool subclasses of int, nested dicts with non-string keys,
    non-finite floats and objects shown by their text; and its line in events.jsonl is
    json.dumps's, character for character."""
    import numpy as np

    class Text(str):
        pass

    fields = {
        "f": 1.234567, "nan": math.nan, "inf": -math.inf, "i": 7, "b": True, "n": None,
        "s": "x", "sub": Text("y"), "f32": np.float32(0.1), "f64": np.float64(2.00004),
        "i64": np.int64(3), "nb": np.bool_(False), "arr": np.array([1.5, np.nan]),
        "tuple": (1.23456, (2, "z")), "nested": {1: 0.12345, "k": [np.int32(4), {2.5: "w"}]},
        "obj": object.__new__(type("Thing", (), {"__str__": lambda self: "thing"})),
        # arrays of every number kind, as a report page's trace holds them
        "f32_2d": np.random.default_rng(0).normal(size=(6, 3)).astype(np.float32) * 100,
        "f64_big": np.random.default_rng(1).normal(size=500) * 1e3,
        "f_inf": np.array([np.inf, -0.0, 1e-9, 12345.67895]),
        "ints": np.arange(-3, 3), "u8": np.array([[0, 255]], np.uint8),
        "bools": np.array([True, False]), "strs": np.array(["a", "b"]),
    }
    log = EventLog(lambda: 0.25, tmp_path / "events.jsonl")
    event = log.add("flight", **fields)
    log.add("lsm", decision="merged", site=None, reason="\u00e9t\u00e9 \"<\\n>\"")
    log.close()
    reference = _reference_clean({"t": 0.25, "kind": "flight", **fields})
    assert event == reference
    assert json.dumps(event) == json.dumps(reference)
    lines = (tmp_path / "events.jsonl").read_text(encoding="utf-8").splitlines()
    assert lines == [json.dumps(e, separators=(",", ":")) for e in log.events]


def test_tree_recorder_logs_every_status_change_with_its_path():
    root = py_trees.composites.Sequence("Root", memory=True, children=[
        py_trees.behaviours.Success("A"),
        py_trees.behaviours.StatusQueue("B", queue=[py_trees.common.Status.RUNNING],
                                        eventually=py_trees.common.Status.FAILURE),
    ])
    tree = py_trees.trees.BehaviourTree(root)
    log = EventLog(lambda: 0.0)
    tree.add_post_tick_handler(TreeStatusRecorder(log))
    tree.tick()
    tree.tick()
    changes = [(e["path"], e["old"], e["new"]) for e in log.events]
    assert ("Root/A", "INVALID", "SUCCESS") in changes
    assert ("Root/B", "INVALID", "RUNNING") in changes
    assert ("Root/B", "RUNNING", "FAILURE") in changes
    assert ("Root", "RUNNING", "FAILURE") in changes
    assert len(changes) == len(set(changes))


def site(id_, x, y, loss=0.1):
    return LandingSite(id=id_, x=x, y=y, z=0.0, roughness=0.1, uncertainty=0.1, size=3.0,
                       obstacle_altitude=0.0, verification_altitude=2.5, first_seen=0.0,
                       last_seen=1.0, detection_count=3, loss=loss)


def flight_data(**changes):
    trace = FlightTrace()
    for i in range(11):
        trace.append(float(i), (3.0 * i, 4.0 * i, 10.0), 100.0 - i)
    trace.phases = [(0.0, "takeoff"), (2.0, "mission"), (5.0, "navigate_to_site"),
                    (9.0, "land"), (10.0, "done")]
    data = dict(
        mission_name="t", seed=1, autopilot="ardupilot", world="flat", detector="scripted",
        trace=trace, end_time=10.0, status="SUCCESS", stop_reason="landed",
        sites=[site(1, 30.0, 40.0, -0.2), site(2, 10.0, 0.0, 0.3)],
        ban_zones=[(5.0, 5.0, 3.0)], chosen_site=site(1, 30.0, 40.0),
        touchdown=(30.3, 40.4, 0.0), touchdown_time=9.5, touchdown_speed=0.4,
        touchdown_safe=True, crashed=False, crash_reason=None, outcome_hint=None,
        failure_reason=None, verification_attempts=2, search_patterns=0, sites_verified=1,
        lsm_counters={"received": 20, "inserted": 3}, perception_counters={},
    )
    data.update(changes)
    return FlightData(**data)


def test_outcome_classification():
    assert classify(flight_data()) == "landed"
    assert classify(flight_data(touchdown_safe=False)) == "landed_unsafe"
    assert classify(flight_data(touchdown_safe=None, lockstep=False)) == "landed_unjudged"
    assert classify(flight_data(outcome_hint="no_site")) == "no_site"
    assert classify(flight_data(crashed=True)) == "crashed"
    assert classify(flight_data(status="FAILURE")) == "aborted"
    assert classify(flight_data(status="RUNNING")) == "aborted"


def test_a_failsafe_landing_is_its_own_outcome_on_safe_ground_or_not():
    for kind in ("battery_critical", "gps_lost"):
        assert classify(flight_data(outcome_hint=kind)) == "failsafe"
        assert classify(flight_data(outcome_hint=kind, touchdown_safe=False)) == "failsafe"
    # The waypoints skipped at the reserve, then a landing at a site: still a landing.
    assert classify(flight_data(outcome_hint="battery_reserve")) == "landed"
    assert classify(flight_data(outcome_hint="battery_critical", crashed=True)) == "crashed"
    summary = build_summary(flight_data(outcome_hint="battery_critical"))
    assert summary["outcome"] == "failsafe" and summary["touchdown_safe"] is True
    first = format_summary(summary).splitlines()[0]
    assert first == ("outcome: failsafe (battery_critical: the battery reached the critical "
                     "level; landed where it was)")


def test_each_outcome_has_its_exit_code_and_says_what_it_means():
    landed = build_summary(flight_data())
    assert (landed["exit_code"], landed["exit_meaning"].split(" (")[0]) == (
        0, "landed on ground the simulator's ground truth judged safe")
    live = build_summary(flight_data(lockstep=False, touchdown_safe=None))
    assert (live["outcome"], live["exit_code"]) == ("landed_unjudged", 3)
    assert "safe" not in live["exit_meaning"] and "not judged" in live["exit_meaning"]
    assert format_summary(live).splitlines()[-1].startswith("exit 3: landed and disarmed")
    lost = build_summary(flight_data(lockstep=False, status="RUNNING",
                                     link_lost="link lost for 30.0 s"))
    assert (lost["outcome"], lost["exit_code"]) == ("link_lost", 4)
    assert "reason: link lost for 30.0 s" in format_summary(lost)
    refused = build_summary(flight_data(lockstep=False, status="INVALID", refused=True))
    assert (refused["outcome"], refused["exit_code"]) == ("refused", 2)
    for outcome in ("landed_unsafe", "crashed", "no_site", "failsafe", "aborted"):
        assert exit_code(outcome) == 1


def test_summary_figures():
    summary = build_summary(flight_data())
    json.dumps(summary)
    assert summary["outcome"] == "landed"
    assert summary["touchdown_error"] == round(math.hypot(0.3, 0.4), 4)
    assert summary["mission_end_time"] == 5.0
    assert summary["time_to_land"] == 4.5
    assert summary["distance"] == 50.0
    assert summary["energy"]["battery_used"] == 10.0
    assert summary["sites_received"] == 20 and summary["sites_retained"] == 2
    assert summary["sites_banned"] == 1 and summary["verification_attempts"] == 2
    text = format_summary(summary)
    assert "outcome: landed" in text and "0.50 m from site 1" in text


def test_report_png_with_and_without_terrain(tmp_path):
    from sitl.terrain import make_terrain

    terrain = make_terrain({"kind": "flat", "size": [100.0, 100.0], "cell_size": 0.5}, seed=0)
    write_report_png(flight_data(terrain=terrain), tmp_path / "a.png", outcome="landed")
    write_report_png(flight_data(sites=[], chosen_site=None, touchdown=None),
                     tmp_path / "b.png")
    for name in ("a.png", "b.png"):
        assert (tmp_path / name).read_bytes()[:4] == b"\x89PNG"


def test_the_report_map_keeps_within_its_pixel_budget():
    """The hill-shaded map is strided to at most ``max_pixels`` a side (its shading costs
    with its area): a 1000-cell world over a 512-pixel budget gives 500 pixels, not 1000."""
    import numpy as np

    from autonomy.report.plot import shaded_terrain
    from sitl.terrain.grid import Terrain

    heights = np.add.outer(np.arange(1000.0), np.arange(1000.0)).astype(np.float32) * 0.01
    terrain = Terrain(heights, cell_size=0.2)
    for budget, side in ((512, 500), (1000, 1000), (999, 500), (300, 250)):
        shaded, extent, grid = shaded_terrain(terrain, (0.0, 200.0, 0.0, 200.0), budget)
        assert shaded.shape == (side, side, 4) and grid.shape == (side, side)
        assert extent[0] == 0.0 and extent[1] <= 200.0
