"""End to end: missions/demo.yaml flown in lockstep against the embedded SITL."""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink import mavutil

from autonomy.cli import main
from autonomy.config import load_mission
from autonomy.report import read_events
from autonomy.runner import REPORT_FILES, fly

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"


@pytest.fixture(scope="module")
def demo_flights(tmp_path_factory):
    """The demo flown twice with the same seed, with reports: through the Python API, then
    through `lander fly` (its exit code, console output and report directory)."""
    first = tmp_path_factory.mktemp("first")
    second = tmp_path_factory.mktemp("second") / "out"
    result = fly(load_mission(DEMO), out_dir=first)
    console = io.StringIO()
    with contextlib.redirect_stdout(console):
        code = main(["fly", str(DEMO), "--out", str(second), "--quiet"])
    return result, (code, console.getvalue(), second)


def test_demo_lands_on_the_chosen_site_on_safe_ground(demo_flights):
    result, _ = demo_flights
    summary = result.summary
    assert summary["outcome"] == "landed"
    assert summary["touchdown_safe"] is True
    site, touchdown = summary["chosen_site"], summary["touchdown"]
    assert math.hypot(touchdown["x"] - site["x"], touchdown["y"] - site["y"]) <= 1.0
    assert summary["touchdown_error"] <= 1.0
    assert site["verified"] is True
    # The demo's best-looking site never verifies: it is banned and the next one is used.
    assert summary["sites_banned"] == 1
    assert summary["verification_attempts"] == 2
    assert summary["time_to_land"] > 0 and summary["distance"] > 100


def test_same_seed_gives_identical_events(demo_flights):
    first, (_, _, second) = demo_flights
    a = (first.out_dir / "events.jsonl").read_bytes()
    b = (second / "events.jsonl").read_bytes()
    assert a == b and len(a) > 0


def test_a_different_seed_gives_different_events(demo_flights):
    first, _ = demo_flights
    other = fly(load_mission(DEMO), seed=first.summary["seed"] + 1)
    assert other.events != first.events
    assert other.summary["outcome"] == "landed"


def test_report_files_exist_and_the_tlog_reads_back(demo_flights):
    result, _ = demo_flights
    for name in REPORT_FILES:
        assert (result.out_dir / name).stat().st_size > 0, name
    summary = json.loads((result.out_dir / "summary.json").read_text())
    assert summary["outcome"] == result.summary["outcome"]
    events = read_events(result.out_dir / "events.jsonl")
    kinds = {e["kind"] for e in events}
    assert {"tree", "phase", "lsm", "perception", "flight"} <= kinds
    assert all(e["t"] >= 0 for e in events)
    assert (result.out_dir / "report.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    log = mavutil.mavlink_connection(str(result.out_dir / "flight.tlog"))
    types = set()
    while (msg := log.recv_match()) is not None:
        types.add(msg.get_type())
    log.close()
    assert {"HEARTBEAT", "COMMAND_LONG", "LOCAL_POSITION_NED"} <= types


def test_lander_fly_writes_the_report(demo_flights):
    _, (code, console, out) = demo_flights  # the demo's second flight, by `lander fly`
    assert code == 0
    assert f"landed (exit 0): report {out / 'report.png'}" in console
    assert all((out / name).exists() for name in REPORT_FILES)


def test_demo_lands_with_the_px4_personality():
    from autonomy.config import apply_overrides

    mission = apply_overrides(load_mission(DEMO), {"vehicle.autopilot": "px4"})
    summary = fly(mission).summary
    assert summary["autopilot"] == "px4"
    assert summary["outcome"] == "landed" and summary["touchdown_error"] <= 1.0


def test_events_are_identical_in_another_process(demo_flights, tmp_path):
    first, _ = demo_flights
    out = tmp_path / "subprocess"
    env = {**os.environ, "PYTHONHASHSEED": "12345"}
    done = subprocess.run(
        [sys.executable, "-m", "autonomy", "fly", str(DEMO), "--out", str(out), "--quiet"],
        env=env, capture_output=True, text=True, timeout=300,
    )
    assert done.returncode == 0, done.stderr
    assert (out / "events.jsonl").read_bytes() == (first.out_dir / "events.jsonl").read_bytes()
