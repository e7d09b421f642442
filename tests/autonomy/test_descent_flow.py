"""The descent watch's camera on the autonomy side: seeds, when it is built, when it gives
no verdict."""

from __future__ import annotations

import numpy as np
import pytest

from autonomy.config import Mission
from autonomy.perception.descent_flow import DescentFlow, calibrate_descent
from autonomy.perception.descent_flow_settings import DescentFlowSettings
from autonomy.runner.world import FlightSeeds, build_descent_flow
from behaviors.ports import VehicleState
from sitl.terrain import Terrain

SMALL = DescentFlowSettings(width=64, height=48, focal_px=32.0, max_corners=200)


def _flat():
    return Terrain(np.zeros((161, 161), np.float32), 0.25, (-20.0, -20.0), kind="flat")


def test_the_watch_seed_leaves_every_other_seed_of_a_flight_as_it_was():
    for seed in (0, 1, 7, 2**32 - 1):
        before = [int(c.generate_state(1, dtype=np.uint32)[0])
                  for c in np.random.SeedSequence(seed).spawn(4)]
        seeds = FlightSeeds.derive(seed)
        assert [seeds.terrain, seeds.sitl, seeds.perception, seeds.tree] == before
        assert seeds.descent_flow not in before


def test_the_watch_is_built_only_when_the_mission_enables_it():
    mission = {"waypoints": [[0.0, 0.0, 10.0]]}
    assert build_descent_flow(Mission.model_validate(mission), _flat(), 1) is None
    mission["landing"] = {"descent_watch": {"enabled": True}}
    assert isinstance(build_descent_flow(Mission.model_validate(mission), _flat(), 1),
                      DescentFlow)


def _state(x, y, z):
    return VehicleState(position=(x, y, z), yaw=0.3)


def test_no_verdict_while_hovering_or_moving_sideways_or_not_watching():
    flow = DescentFlow(_flat(), SMALL, seed=2)
    flow.update(_state(0, 0, 10), 0.0)
    assert flow.counters["frames"] == 0  # not watching: nothing rendered
    flow.watch(True)
    flow.update(_state(0, 0, 10.0), 0.0)
    flow.update(_state(0, 0, 10.0), 0.2)  # hovering
    assert flow.latest() is None
    flow.update(_state(1.0, 0, 9.8), 0.4)  # 1 m sideways for 0.2 m down
    assert flow.latest() is None and flow.counters["sideways"] == 1
    flow.update(_state(1.0, 0, 9.5), 0.6)  # descending: a verdict, no obstacle on flat ground
    sighting = flow.latest()
    assert sighting is not None and sighting.time == 0.6 and not sighting.obstacle
    flow.watch(False)
    assert flow.latest() is None


def test_calibration_refuses_a_descent_that_gives_no_frames():
    with pytest.raises(ValueError, match="top"):
        calibrate_descent(_flat(), 0.0, 0.0, settings=SMALL, top=2.0, bottom=3.0)


def test_lander_flow_calibrate_prints_the_thresholds_to_paste(tmp_path, capsys):
    from autonomy.cli import main

    mission = tmp_path / "m.yaml"
    mission.write_text(
        "waypoints: [[0.0, 0.0, 20.0]]\n"
        "world: {kind: flat, size: [60.0, 60.0], cell_size: 0.25}\n"
        "perception: {descent_flow: {width: 64, height: 48, focal_px: 32.0, rate: 2.0}}\n"
    )
    assert main(["flow-calibrate", str(mission), "--at", "5,5", "--top", "12"]) == 0
    out = capsys.readouterr().out
    o_t = float(out.split("obstacle_threshold:")[1].split()[0])
    v_t = float(out.split("variance_threshold:")[1].split()[0])
    assert o_t > 0 and v_t > 0 and "frame pairs" in out
    assert main(["flow-calibrate", str(mission), "--at", "500,5"]) == 2
    assert "--at 500,5: no ground of the world there" in capsys.readouterr().err


def test_lander_flow_calibrate_leaves_moving_obstacles_out_unless_asked(tmp_path, capsys):
    from autonomy.cli import main

    base = ("waypoints: [[0.0, 0.0, 20.0]]\n"
            "perception: {descent_flow: {width: 64, height: 48, focal_px: 32.0, rate: 2.0}}\n")
    world = "world: {kind: flat, size: [60.0, 60.0], cell_size: 0.25%s}\n"
    car = (", moving_obstacles: {paths: [{kind: vehicle, path: [[7.0, -20.0], [7.0, 20.0]], "
           "speed: 4.0}]}")
    static, busy = tmp_path / "static.yaml", tmp_path / "busy.yaml"
    static.write_text(base + world % "")
    busy.write_text(base + world % car)

    def thresholds(*argv):
        assert main(["flow-calibrate", *argv, "--at", "5,0", "--top", "12"]) == 0
        out = capsys.readouterr().out
        return out, [float(out.split(key)[1].split()[0])
                     for key in ("obstacle_threshold:", "variance_threshold:")]

    _, alone = thresholds(str(static))
    out, left_out = thresholds(str(busy))
    assert left_out == alone and "1 moving obstacle(s) left out" in out
    out, kept = thresholds(str(busy), "--with-moving")
    assert kept != alone and "with the world's 1 moving obstacle(s)" in out
