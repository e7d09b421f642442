"""A vehicle's home that moves during a flight (a ground station's MAV_CMD_DO_SET_HOME): the
flight keeps the frame it took off in, so it lands on the same ground as without the move,
and the move is recorded (events.jsonl, summary.json, the console). Flown through ``lander
fly`` against the embedded SITL, in lockstep and live."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from autonomy.cli import main
from autonomy.cli.demo import mission_path
from sitl import SitlSettings

DEMO = mission_path("demo.yaml")
# 45 s into demo.yaml's flight the first sites are known and the vehicle is on its way to one.
MOVE = ["--set", "sitl.home_change.at=45", "--set", "sitl.home_change.east=30",
        "--set", "sitl.home_change.north=0"]


def fly(tmp_path: Path, name: str, *args: str) -> tuple[int, dict, list[dict]]:
    out = tmp_path / name
    code = main(["fly", str(DEMO), "--out", str(out), *args])
    summary = json.loads((out / "summary.json").read_text())
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    return code, summary, events


def found_sites(events: list[dict], before: float) -> bool:
    return any(e.get("kind") == "lsm" and e["t"] < before for e in events)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_home_moved_in_flight_lands_on_the_same_ground_and_is_reported(
        autopilot, tmp_path, capsys):
    personality = ["--set", f"vehicle.autopilot={autopilot}"]
    code, still, _ = fly(tmp_path, "still", *personality)
    assert (code, still["outcome"], still["home_moves"]) == (0, "landed", None)
    capsys.readouterr()

    code, moved, events = fly(tmp_path, "moved", *personality, *MOVE)
    assert (code, moved["outcome"]) == (0, "landed")
    assert found_sites(events, before=45.0)
    # Lockstep touchdowns are the simulator's truth: the same ground, the same site.
    a, b = still["touchdown"], moved["touchdown"]
    assert math.hypot(a["x"] - b["x"], a["y"] - b["y"]) < 0.3
    assert moved["chosen_site"]["id"] == still["chosen_site"]["id"]
    assert moved["touchdown_error"] < 0.3

    (move,) = [e for e in events if e.get("event") == "home_moved"]
    assert move["t"] == pytest.approx(45.0, abs=0.2)
    assert move["distance"] == pytest.approx(30.0, abs=0.1)
    assert move["position"] == pytest.approx([30.0, 0.0, 0.0], abs=0.1)
    line = move["text"]
    assert line.startswith("home moved by 30.0 m (to 47.39774")
    assert "this flight keeps its frame from takeoff" in line
    assert [m["text"] for m in moved["home_moves"]] == [line]
    # Latitude and longitude kept to 1e-7 degrees (1 cm), not to the 4 decimals (11 m) of
    # other floats: 30 m east of demo.yaml's home (47.397742, 8.545594) is 8.5459921.
    assert move["previous"][:2] == [47.397742, 8.545594]
    assert move["home"][0] == pytest.approx(47.397742, abs=1e-6)  # 10 cm
    assert move["home"][1] == pytest.approx(8.5459921, abs=1e-6)
    out = capsys.readouterr().out
    assert f"[   45.0 s] {line}" in out  # when it happens
    assert f"\n{line}\n" in out  # and in the closing summary


def test_a_bad_home_change_names_the_field(capsys):
    code = main(["fly", str(DEMO), "--set", "sitl.home_change.at=-1",
                 "--set", "sitl.home_change.east=30", "--set", "sitl.home_change.north=0"])
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert "sitl.home_change.at" in line and "must be >= 0" in line


def test_live_flight_keeps_its_frame_when_home_moves(served_sitl, tmp_path, capsys):
    settings = SitlSettings(home_change={"at": 45.0, "east": 30.0, "north": 0.0})
    served = served_sitl(speedup=10.0, settings=settings)
    code, summary, events = fly(tmp_path, "live", "--connect", served.url)
    assert (code, summary["outcome"]) == (3, "landed_unjudged")
    (move,) = summary["home_moves"]
    assert move["distance"] == pytest.approx(30.0, abs=0.1)
    assert any(e.get("event") == "home_moved" for e in events)
    # Where the vehicle really is: on demo.yaml's site 2 (25, 55), not 30 m east of it.
    x, y, _ = served.sitl.truth.position
    assert math.hypot(x - 25.0, y - 55.0) < 0.5
    assert not served.sitl.truth.armed
    assert "this flight keeps its frame from takeoff" in capsys.readouterr().out
