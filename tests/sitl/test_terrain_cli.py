"""``lander terrain``: build a world from the command line, with its pictures."""

from __future__ import annotations

import numpy as np
import pytest

from autonomy.cli import main


def test_terrain_command_writes_the_world_and_a_depth_view(tmp_path, capsys):
    out = tmp_path / "out"
    code = main([
        "terrain", "--kind", "rubble", "--seed", "4", "--set", "size=[80, 60]",
        "--set", "cell_size=0.25", "--out", str(out), "--save-grid",
        "--depth-at", "5,-3,30,45",
    ])  # fmt: skip
    assert code == 0
    text = capsys.readouterr().out
    assert "world rubble seed 4: 321 x 241 cells of 0.25 m" in text
    assert "safe ground" in text and "lander detect --depth" in text
    for name in ("terrain.png", "terrain.npy", "depth.npy", "depth.png"):
        assert (out / name).stat().st_size > 0
    grid = np.load(out / "terrain.npy")
    assert grid.shape == (241, 321)
    depth = np.load(out / "depth.npy")
    assert depth.shape == (256, 256) and np.isfinite(depth).mean() > 0.99


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--set", "rock_density=-1"], "--set rock_density"),
        (["--set", "rock_density"], "expected key=value"),
        (["--kind", "file", "--set", "path=missing.asc"], "--set path"),
        (["--depth-at", "1,2"], "--depth-at"),
        (["--set", "size=[50,50]", "--depth-at", "500,0,20"], "outside the world"),
    ],
)
def test_terrain_command_reports_bad_input_in_one_line(tmp_path, capsys, argv, message):
    code = main(["terrain", "--out", str(tmp_path), *argv])
    assert code == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
