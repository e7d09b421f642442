"""Moving obstacles from the command line: ``lander validate`` refuses bad settings in one
line (exit 2); ``lander terrain`` lists them and draws their paths."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from autonomy.cli import main

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"


@pytest.mark.parametrize(("moving", "words"), [
    ({"paths": [{"kind": "person", "path": [[500, 0]]}]},
     "world.moving_obstacles.paths.0.path.0: (500, 0) is off the world"),
    ({"paths": [{"kind": "dog", "path": [[0, 0]]}]}, "world.moving_obstacles.paths.0.kind"),
    ({"count": 3, "vehicle_speed": [9, 2]}, "world.moving_obstacles.vehicle_speed"),
    ({"count": 3, "area": [900, 0, 10]}, "world.moving_obstacles.area: centre (900, 0)"),
    ({"cout": 3}, "world.moving_obstacles.cout: unknown setting"),
])
def test_validate_refuses_bad_moving_obstacles_in_one_line(tmp_path, capsys, moving, words):
    doc = yaml.safe_load(DEMO.read_text())
    doc["world"]["moving_obstacles"] = moving
    _refused_in_one_line(doc, tmp_path, capsys, words)


def _refused_in_one_line(doc, tmp_path, capsys, words):
    """``lander validate`` refuses the mission ``doc`` with exit 2 and one line of ``words``."""
    path = tmp_path / "moving.yaml"
    path.write_text(yaml.safe_dump(doc))
    assert main(["validate", str(path)]) == 2
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in captured.err + captured.out
    assert lines[0].startswith("lander validate: error: ") and words in lines[0]


def test_terrain_lists_the_moving_obstacles_and_draws_their_paths(tmp_path, capsys):
    args = ["terrain", "--kind", "urban", "--seed", "2", "--set", "size=[120, 120]",
            "--set", "cell_size=0.5", "--out"]
    assert main([*args, str(tmp_path / "still")]) == 0
    still = capsys.readouterr().out
    assert main([*args, str(tmp_path / "busy"), "--set",
                 "moving_obstacles={count: 8, vehicle_fraction: 0.5}"]) == 0
    busy = capsys.readouterr().out
    assert "moving obstacles" not in still
    line = next(s for s in busy.splitlines() if s.startswith("moving obstacles: "))
    people, vehicles = (int(line.split()[i]) for i in (2, 4))
    assert people + vehicles == 8
    # the same world under them, with the paths drawn over it
    assert still.splitlines()[1] == busy.splitlines()[1]
    assert (tmp_path / "busy" / "terrain.png").read_bytes() != (
        tmp_path / "still" / "terrain.png").read_bytes()


def _model(tmp_path) -> Path:
    import numpy as np

    path = tmp_path / "model.npy"
    np.save(path, np.zeros((161, 161), np.float32))  # 40 m square at 0.25 m, home central
    return path


def test_an_elevation_model_takes_moving_obstacles_on_given_paths(tmp_path, capsys):
    model = _model(tmp_path)
    moving = "moving_obstacles={paths: [{kind: vehicle, path: [[5, -15], [5, 15]], speed: 3}]}"
    args = ["terrain", "--kind", "file", "--set", f"path={model}", "--set",
            "source_cell_size=0.25", "--set", "cell_size=0.25", "--set", moving]
    assert main([*args, "--out", str(tmp_path / "busy")]) == 0
    line = next(s for s in capsys.readouterr().out.splitlines()
                if s.startswith("moving obstacles: "))
    assert line.split()[2:5] == ["0", "people,", "1"]


@pytest.mark.parametrize(("moving", "words"), [
    ({"paths": [{"kind": "person", "path": [[0, 0], [30, 0]]}]},
     "world.moving_obstacles.paths.0.path.1: (30, 0) is off the elevation model "
     "(x -20 .. 20, y -20 .. 20 m about home)"),
    ({"count": 2}, "world.moving_obstacles.count: 2 random obstacles need a generated world"),
])
def test_validate_refuses_moving_obstacles_off_an_elevation_model_in_one_line(
        tmp_path, capsys, moving, words):
    doc = {"waypoints": [[0.0, 0.0, 10.0]], "landing": {"search_rectangle": [10.0, 10.0],
                                                         "pattern_center_radius": 2.0},
           "world": {"kind": "file", "path": str(_model(tmp_path)), "source_cell_size": 0.25,
                     "cell_size": 0.25, "moving_obstacles": moving}}
    _refused_in_one_line(doc, tmp_path, capsys, words)
