"""What a new user once broke, each now one clear line (exit 2) or a written report.

Each case is from issue 17's list of what was seen: values the schema used to let through to
a traceback, seeds below zero, missions too big to fly, what ``validate`` accepted and
``fly`` refused, an empty field name, and Ctrl-C in a lockstep flight.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from autonomy.cli import main
from autonomy.cli.demo import mission_path
from autonomy.config import Mission
from autonomy.runner import fly
from autonomy.runner.progress import FlightProgress

DEMO = mission_path("demo.yaml")  # the quick rehearsal mission
REPO = Path(__file__).resolve().parents[2]


def one_error_line(capsys, command: str) -> str:
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    assert lines[0].startswith(f"lander {command}: error: "), lines[0]
    assert "Traceback" not in captured.err + captured.out
    return lines[0]


def write_demo(tmp_path: Path, **changes) -> Path:
    doc = yaml.safe_load(DEMO.read_text())
    for dotted, value in changes.items():
        node = doc
        *parents, last = dotted.split("__")
        for key in parents:
            node = node.setdefault(key, {})
        node[last] = value
    path = tmp_path / "mission.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize(
    ("setting", "words"),
    [
        ("lsm.capacity=1e23", "override lsm.capacity: must be <= 100000"),
        ("lsm.capacity=1000000000", "override lsm.capacity: must be <= 100000"),
        ("landing.verification_altitude=1e308",
         "override landing.verification_altitude: must be <= 10000"),
        ("waypoints=[[1e39,0,30]]", "override waypoints: waypoints.0.0: must be <= 50000"),
        ("perception.rate=100", "override perception.rate: 100.0 Hz is faster than tick_rate"),
        ("lsm.capacity=true", "override lsm.capacity: must be a number, not true or false"),
    ],
)
def test_fly_refuses_values_beyond_the_schema_with_one_line(tmp_path, capsys, setting, words):
    out = tmp_path / "out"
    assert main(["fly", str(DEMO), "--set", setting, "--out", str(out)]) == 2
    line = one_error_line(capsys, "fly")
    assert words in line, line
    assert " : " not in line and "override :" not in line  # never an empty field name
    assert not out.exists()


@pytest.mark.parametrize(
    "argv",
    [
        ["fly", str(DEMO), "--seed", "-5"],
        ["sitl", "--seed", "-1"],
        ["detect", "--seed", "-1", "--lidar", "cloud.npy"],
        ["terrain", "--seed", "-1"],
        ["campaign", str(DEMO), "--runs", "1", "--seed", "4294967296"],
    ],
)
def test_seeds_outside_0_to_2_32_are_refused_by_the_flag_itself(capsys, argv):
    assert main(argv) == 2
    line = one_error_line(capsys, argv[0])
    assert "argument --seed: must be 0 .. 2**32-1" in line, line


def test_a_seed_out_of_range_is_refused_by_the_python_api_too():
    mission = Mission(waypoints=[(0, 10, 20)])
    with pytest.raises(Exception, match="seed: must be an integer 0 .. 2\\*\\*32-1"):
        fly(mission, seed=-5)


def test_ten_thousand_waypoints_are_refused_at_once(tmp_path, capsys):
    path = write_demo(tmp_path, waypoints=[[float(i % 50), 10.0, 30.0] for i in range(10_000)])
    assert main(["validate", str(path)]) == 2
    line = one_error_line(capsys, "validate")
    assert f"{path}:" in line and "waypoints: at most 1000 items" in line


@pytest.mark.parametrize(
    ("change", "field", "words"),
    [
        ({"vehicle__connection": "bogus://x"}, "vehicle.connection", "unknown link"),
        ({"vehicle__connection": "sim"}, "vehicle.connection",
         "the simulator link is written sim://"),
        ({"vehicle__connection": "tcp:127.0.0.1"}, "vehicle.connection", "HOST:PORT"),
        ({"vehicle__signing_key_env": "LANDER_NOT_SET_ANYWHERE"}, "vehicle.signing_key_env",
         "environment variable LANDER_NOT_SET_ANYWHERE is not set"),
        ({"waypoints": [[40_000_000.0, 0.0, 30.0]]}, "waypoints.0.0", "must be <= 50000"),
        ({"waypoints": [{"lat": 48.0, "lon": 8.5}]}, "waypoints.0",
         "m from home, more than the 50000 m a multicopter flies"),
        ({"lsm__capacity": True}, "lsm.capacity", "must be a number, not true or false"),
        ({"seed": -5}, "seed", "must be >= 0"),
        ({"time_limit": 1e308}, "time_limit", "must be <= 14400"),
    ],
)
def test_validate_refuses_what_fly_would_refuse(tmp_path, capsys, monkeypatch, change, field,
                                                 words):
    monkeypatch.delenv("LANDER_NOT_SET_ANYWHERE", raising=False)
    path = write_demo(tmp_path, **change)
    assert main(["validate", str(path)]) == 2
    line = one_error_line(capsys, "validate")
    assert f"{path}:" in line and f": {field}: " in line and words in line, line
    assert main(["fly", str(path), "--out", str(tmp_path / "out")]) == 2
    assert one_error_line(capsys, "fly").split("error: ", 1)[1] == line.split("error: ", 1)[1]


def test_a_corrupt_world_file_is_refused_by_validate_with_its_line(tmp_path, capsys):
    (tmp_path / "dem.npy").write_bytes(b"\x93NUMPY\x01\x00{'descr': '<f8', 'fortran_order")
    path = write_demo(tmp_path, world={"kind": "file", "path": "dem.npy",
                                       "source_cell_size": 1.0})
    assert main(["validate", str(path)]) == 2
    line = one_error_line(capsys, "validate")
    assert ": world.path: cannot read " in line and "not" not in line.split("world.path")[0]


def test_argparse_errors_are_one_line_naming_the_command(capsys):
    assert main(["fly"]) == 2
    line = one_error_line(capsys, "fly")
    assert "the following arguments are required: MISSION.yaml" in line
    assert "(see lander fly --help)" in line


def test_a_lockstep_flight_reports_progress(tmp_path):
    import io

    mission = Mission.model_validate(yaml.safe_load(DEMO.read_text()))
    stream = io.StringIO()
    result = fly(mission, out_dir=None, progress=FlightProgress(
        "demo", mission.time_limit, len(mission.waypoints), stream=stream, plain_every=0.0))
    assert result.outcome == "landed"
    lines = stream.getvalue().splitlines()
    assert lines and all(line.startswith("flying demo: ") for line in lines)
    assert "of 600 s simulated" in lines[-1] and "Ctrl-C stops" in lines[-1]


def test_ctrl_c_in_a_lockstep_flight_writes_the_report_marked_interrupted(tmp_path):
    out = tmp_path / "out"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    process = subprocess.Popen(
        [sys.executable, "-m", "autonomy", "fly", str(REPO / "missions" / "mars_science.yaml"),
         "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path, env=env,
    )
    try:
        for line in process.stdout:  # the first phase line: the flight is under way
            if line.startswith("["):
                process.send_signal(signal.SIGINT)
                break
        stdout, stderr = process.communicate(timeout=100)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 1, stderr
    assert "Traceback" not in stderr
    assert "interrupted (Ctrl-C)" in stdout
    for name in ("summary.json", "events.jsonl", "flight.tlog", "report.png"):
        assert (out / name).stat().st_size > 0, name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True and summary["outcome"] == "aborted"
    events = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()]
    assert events[-1]["event"] == "end" and events[-1]["reason"] == "interrupted (Ctrl-C)"
