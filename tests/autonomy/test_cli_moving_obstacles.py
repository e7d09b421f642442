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
