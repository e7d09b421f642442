"""Live mode: the runner flies a SITL served over TCP faster than real time, on the
vehicle's own time; Ctrl-C lands it."""

from __future__ import annotations

import _thread
import threading
from pathlib import Path

from autonomy.config import apply_overrides, load_mission
from autonomy.report.events import EventLog
from autonomy.runner import fly

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"


def live_mission(url: str, **overrides):
    return apply_overrides(load_mission(DEMO), {"vehicle.connection": url, **overrides})


def test_ctrl_c_in_live_mode_lands_the_vehicle(served_sitl, tmp_path):
    served = served_sitl(speedup=8.0)
    sitl = served.sitl
    mission = live_mission(served.url, time_limit=120.0)
    airborne = threading.Event()
    done = threading.Event()

    def interrupt_when_airborne():
        # Ctrl-C once the vehicle has climbed a few metres (read from the simulator).
        while not done.is_set():
            if sitl.truth.position[2] > 4.0:
                airborne.set()
                _thread.interrupt_main()
                return
            done.wait(0.05)

    watcher = threading.Thread(target=interrupt_when_airborne, daemon=True)
    watcher.start()
    try:
        result = fly(mission, out_dir=tmp_path, on_interrupt="land")
    finally:
        done.set()
        watcher.join(timeout=5)
    assert airborne.is_set()
    summary = result.summary
    assert summary["outcome"] == "aborted" and summary["exit_code"] == 1
    assert summary["mode"] == "live" and summary["realtime_factor"] is None
    assert summary["stop_reason"].startswith("interrupted (land")
    truth = sitl.truth
    assert truth.landed and not truth.armed and not truth.crashed
    assert summary["touchdown"] is not None  # seen from the autopilot's landed state
    kinds = [e.get("event") for e in result.events if e["kind"] == "flight"]
    assert "land" in kinds and "touchdown" in kinds


def test_a_live_flight_runs_on_the_vehicles_time_at_any_speedup(
    served_sitl, tmp_path, monkeypatch
):
    # At 20x in wall time the verification hover must still last its 8 s of the SITL's
    # simulated time (on wall time it lasted 160 simulated seconds).
    served = served_sitl(speedup=20.0)
    sitl = served.sitl
    mission = live_mission(served.url)
    phases: list[tuple[str, float, float]] = []  # (phase, clock t, SITL time when logged)
    on_disk: list[int] = []  # phase events in events.jsonl as each next phase is logged
    add = EventLog.add

    def stamped_add(log, kind, **fields):
        # Each phase is stamped with the simulator's own time in the flight's thread, as
        # it is logged: a thread tailing events.jsonl instead lags by however long the
        # machine takes to schedule it, half a simulated second at 20x on a loaded machine.
        event = add(log, kind, **fields)
        if kind == "phase":
            phases.append((event["phase"], event["t"], sitl.time))
            written = tmp_path / "events.jsonl"
            text = written.read_text(encoding="utf-8") if written.exists() else ""
            on_disk.append(text.count('"kind":"phase"'))
        return event

    monkeypatch.setattr(EventLog, "add", stamped_add)
    result = fly(mission, out_dir=tmp_path)
    summary = result.summary
    assert summary["outcome"] == "landed_unjudged" and summary["exit_code"] == 3
    names = [p for p, _, _ in phases]
    first = names.index("verification")  # the demo's first site fails: a full hover
    hover = phases[first + 1][2] - phases[first][2]
    assert abs(hover - mission.landing.verification_duration) < 0.5
    # The flight's clock is the vehicle's: from takeoff to done it counts the simulated time.
    (_, t0, sim0), (_, t1, sim1) = phases[names.index("takeoff")], phases[-1]
    assert names[-1] == "done"
    assert abs((t1 - t0) - (sim1 - sim0)) < 0.02 * (sim1 - sim0)
    # events.jsonl follows the flight tick by tick (tail -f): when a phase begins, the
    # phases before it, logged in earlier ticks, are on disk.
    assert on_disk == list(range(len(phases))), on_disk
