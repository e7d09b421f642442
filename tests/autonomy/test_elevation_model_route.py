"""A mission over an elevation model stays on it: waypoints, search patterns and new
pattern centres that could leave the model are refused at validation, with the coordinates
(issue 16: flights over a small real model landed off it)."""

from __future__ import annotations

import numpy as np
import pytest

import autonomy.cli as cli


@pytest.fixture(autouse=True)
def only_validate(monkeypatch):
    monkeypatch.setattr(cli, "COMMAND_MODULES", ("autonomy.cli.validate",))


def mission(tmp_path, waypoints, landing=""):
    np.save(tmp_path / "dem.npy", np.zeros((121, 71), dtype=np.float32))  # 70 m x 120 m
    path = tmp_path / "m.yaml"
    path.write_text(
        "cruise_altitude: 20\nwaypoints:\n"
        + "".join(f"  - [{x}, {y}, 20]\n" for x, y in waypoints)
        + "world: {kind: file, path: dem.npy, source_cell_size: 1.0}\n" + landing
    )
    return path


SMALL = "landing: {search_rectangle: [20, 20], pattern_center_radius: 10}\n"


def test_a_route_with_its_patterns_on_the_model_is_valid(tmp_path, capsys):
    assert cli.main(["validate", str(mission(tmp_path, [(5, 10), (-5, -20)], SMALL))]) == 0


@pytest.mark.parametrize(
    ("waypoints", "landing", "words"),
    [
        ([(5, 10), (40, 0)], SMALL, "waypoints.1: (40, 0) is off the elevation model "
         "(x -35 .. 35, y -60 .. 60 m about home)"),
        ([(30, 0), (0, 0)], SMALL, "landing.search_rectangle: a 20 x 20 m search pattern "
         "around waypoints.0 (30, 0) reaches (40, 0)"),
        ([(0, 0)], "", "pattern_center_radius: new 60 x 40 m search patterns centred "
         "within 50 m of the last waypoint (0, 0) may reach (-80, -70)"),
    ],
)
def test_a_route_leaving_the_model_is_refused_with_the_coordinates(
    tmp_path, capsys, waypoints, landing, words
):
    assert cli.main(["validate", str(mission(tmp_path, waypoints, landing))]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and words in err, err
