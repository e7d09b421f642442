"""`lander validate`, `lander tree`, `lander fly` (bad input) and `lander demo` from the CLI."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from autonomy.cli import main
from autonomy.cli.demo import demo_mission_path, mission_path

# The quick rehearsal mission (scripted sites over flat ground) for everything but the demo.
SCRIPTED = mission_path("demo.yaml")

BAD = """\
waypoints:
  - [0, 50, -30]
landing:
  verification_duration: 0
  typo_field: 1
seed: -4
"""


def test_validate_ok(capsys):
    assert main(["validate", str(SCRIPTED)]) == 0
    assert capsys.readouterr().out.startswith("ok: ")


def test_validate_prints_one_line_per_problem_and_exits_2(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(BAD)
    assert main(["validate", str(path)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert captured.out == ""
    expected = [(2, "waypoints.0.2"), (4, "landing.verification_duration"),
                (5, "landing.typo_field"), (6, "seed")]
    assert len(lines) == len(expected)
    for line, (number, field) in zip(lines, expected, strict=True):
        assert line.startswith(f"lander validate: error: {path}:{number}: {field}: "), line
    assert "Traceback" not in captured.err


def test_validate_yaml_syntax_error(tmp_path, capsys):
    path = tmp_path / "broken.yaml"
    path.write_text("waypoints:\n  - [1, 2, 3\nseed: 1\n")
    assert main(["validate", str(path)]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert f"{path}:3: YAML syntax error" in line


def test_validate_missing_file(tmp_path, capsys):
    assert main(["validate", str(tmp_path / "nope.yaml")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "cannot read mission file" in line


@pytest.mark.parametrize(
    "url", ["bogus://x", "udp:not-an-address", "tcp:127.0.0.1:99999", "sim://inav"]
)
def test_fly_bad_connection_exits_2_with_one_line(tmp_path, capsys, url):
    out = tmp_path / "out"
    assert main(["fly", str(SCRIPTED), "--connect", url, "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lander fly: error: "), err


def test_fly_bad_mission_exits_2(tmp_path, capsys):
    path = tmp_path / "bad.yaml"
    path.write_text(BAD)
    assert main(["fly", str(path), "--out", str(tmp_path / "out")]) == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 4
    assert not (tmp_path / "out").exists()


def test_tree_prints_ascii_and_writes_dot(tmp_path, capsys):
    dot = tmp_path / "mission.dot"
    assert main(["tree", str(SCRIPTED), "--dot", str(dot)]) == 0
    out = capsys.readouterr().out
    for name in ("Preflight", "Takeoff", "Waypoint 3", "LandingSiteVerification", "Land"):
        assert name in out
    text = dot.read_text()
    assert text.startswith("digraph") and "LandingSiteVerification" in text


def test_tree_unwritable_dot_exits_2(tmp_path, capsys):
    assert main(["tree", str(SCRIPTED), "--dot",
                 str(tmp_path / "missing-dir" / "x.dot")]) == 2
    assert capsys.readouterr().err.startswith("lander tree: error: --dot")


def test_demo_mission_is_found_from_anywhere(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    path = demo_mission_path()
    assert path.name == "mars_demo.yaml" and Path(path).is_file()


def test_demo_shows_the_detector_and_a_failed_then_successful_verification(tmp_path, capsys):
    """What the README promises of `make demo`: terrain, the elevation-map detector in the
    loop, a site banned after its verification hover, a landing on a verified site. If a
    change to the detector or the world makes the first site verify, pick a seed that shows
    the failure again: `lander campaign missions/mars_demo.yaml --runs 8` lists
    verification_attempts and sites_banned per seed in runs.jsonl."""
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "outcome: landed" in text
    assert f"report: {out / 'report.png'}" in text
    assert "1 failed verification and was banned" in text
    assert (out / "report.png").exists()
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["world"], summary["detector"]) == ("mars", "elevation_map")
    assert summary["sites_banned"] >= 1
    assert summary["verification_attempts"] == summary["sites_banned"] + 1
    assert summary["chosen_site"]["verified"] and summary["touchdown_safe"] is True


def test_fly_unusable_out_dir_exits_2(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    assert main(["fly", str(SCRIPTED), "--out", str(blocker / "out")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert "cannot create the report directory" in line


def test_fly_set_overrides_settings(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["fly", str(SCRIPTED), "--out", str(out), "--quiet",
                 "--set", "time_limit=15", "--set", "vehicle.autopilot=px4"])
    assert code == 1  # the time limit cuts the flight short
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "aborted" and summary["autopilot"] == "px4"
    capsys.readouterr()
    assert main(["fly", str(SCRIPTED), "--set", "landing.nope=1"]) == 2
    assert "landing.nope: unknown setting" in capsys.readouterr().err
    assert main(["fly", str(SCRIPTED), "--set", "novalue"]) == 2
    assert "expected KEY=VALUE" in capsys.readouterr().err
