"""The approach chosen by the mission (landing.approach.method): the trajectory of
seed 003 over the vehicle's elevation map, with the thesis's climb-traverse-descent as its
fallback, through the built-in tree, the runner and the CLI."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from autonomy.cli import main
from autonomy.config import apply_overrides, load_mission
from autonomy.perception.approach import MapApproachPlanner
from autonomy.report import read_events
from autonomy.runner import fly
from behaviors.settings import ApproachSettings
from lsd.elevation.map import ElevationMap
from lsd.elevation.settings import ElevationMapSettings

MISSIONS = Path(__file__).resolve().parents[2] / "missions"


def test_the_tree_has_the_trajectory_approach_only_when_the_mission_asks(tmp_path, capsys):
    mission = (MISSIONS / "demo.yaml").read_text()
    chosen = tmp_path / "trajectory.yaml"
    chosen.write_text(mission + "\nlanding:\n  approach:\n    method: trajectory\n"
                      if "\nlanding:" not in mission else mission.replace(
                          "\nlanding:\n", "\nlanding:\n  approach: {method: trajectory}\n", 1))
    assert main(["validate", str(chosen)]) == 0
    assert main(["tree", str(chosen)]) == 0
    with_trajectory = capsys.readouterr().out
    assert main(["tree", str(MISSIONS / "demo.yaml")]) == 0
    default = capsys.readouterr().out
    assert "FlyApproachTrajectory" in with_trajectory and "Approach" in with_trajectory
    assert "FlyApproachTrajectory" not in default
    assert default.count("NavigateToSite") == with_trajectory.count("NavigateToSite")


def test_without_a_terrain_map_the_mission_flies_the_thesis_approach_and_lands(tmp_path):
    """The scripted detector builds no map: each try's trajectory says why, the tree flies
    the clear-altitude approach instead, and the flight lands as it does by default."""
    mission = apply_overrides(load_mission(MISSIONS / "demo.yaml"),
                              {"landing.approach.method": "trajectory"})
    result = fly(mission, out_dir=tmp_path)
    assert result.summary["outcome"] == "landed"
    events = read_events(tmp_path / "events.jsonl")
    tried = [e for e in events if e.get("behaviour") == "FlyApproachTrajectory"
             and e.get("new") == "FAILURE"]
    assert tried and all("no terrain map" in e["feedback"] for e in tried)
    flown = [e for e in events if e.get("behaviour") == "NavigateToSite"
             and e.get("new") == "SUCCESS"]
    assert len(flown) >= len(tried)


def _map_with_a_wall() -> ElevationMap:
    m = ElevationMap(ElevationMapSettings(size=40.0, resolution=0.5))
    m.origin_index[:] = (-40, -40)  # the window covers -20 .. 20 m
    m.mean[:] = 0.0
    m.top[:] = 0.1
    m.variance[:] = 0.01
    m.top[38:42, 10:70] = 25.0  # a 25 m wall across x = -1 .. 1 m, y = -15 .. 15 m
    return m


def test_the_map_planner_goes_around_what_the_map_shows_and_says_when_it_cannot():
    planner = MapApproachPlanner(_map_with_a_wall(), ApproachSettings(method="trajectory"))
    planned = planner.plan((-10.0, 0.0, 15.0), (10.0, 0.0, 15.0))
    assert not isinstance(planned, str), planned
    t = np.linspace(0.0, planned.duration, 400)
    xs = np.array([planned.state_at(float(ti))[0] for ti in t])
    crossing = xs[np.abs(xs[:, 0]) < 1.5]
    assert len(crossing) and np.all(np.abs(crossing[:, 1]) > 15.0)  # around the wall's end
    end, velocity = planned.state_at(planned.duration)
    assert end == pytest.approx((10.0, 0.0, 15.0)) and np.allclose(velocity, 0.0, atol=1e-9)
    assert "outside the mapped area" in planner.plan((0.0, -10.0, 15.0), (50.0, 0.0, 15.0))
    # A goal beside (here on) the wall is raised to keep the margin over it to the end;
    # the margin is the mission's clear_altitude_buffer unless vertical_margin says otherwise.
    over = planner.plan((-10.0, 0.0, 15.0), (0.0, 0.0, 15.0))
    assert over.state_at(over.duration)[0][2] == pytest.approx(25.0 + 2 * 0.1 + 10.0, abs=0.2)
    # Ground never seen across the whole window: no way over it, nor around.
    unseen = _map_with_a_wall()
    unseen.top[38:42, :] = unseen.mean[38:42, :] = np.nan
    assert "no path" in MapApproachPlanner(unseen, planner.settings).plan(
        (-10.0, 0.0, 15.0), (10.0, 0.0, 15.0))


def test_the_demo_over_mars_lands_safely_along_a_planned_trajectory():
    # The demo mission (mars_demo: elevation-map detector over the Mars world) with the
    # trajectory approach: at least one approach is flown along its trajectory to arrival,
    # not handed to the fallback, and the flight ends on ground the truth judges safe.
    mission = apply_overrides(load_mission(MISSIONS / "mars_demo.yaml"),
                              {"landing.approach.method": "trajectory"})
    result = fly(mission, seed=2)
    assert result.outcome == "landed" and result.summary["touchdown_safe"] is True
    arrived = [e for e in result.events if e.get("kind") == "tree"
               and e.get("behaviour") == "FlyApproachTrajectory" and e.get("new") == "SUCCESS"]
    assert arrived and all(e["feedback"] == "arrived" for e in arrived)
    assert result.summary["collisions"] == 0


def test_the_mars_survey_lands_safely_with_its_retries_flown_along_planned_trajectories():
    # The Mars science mission (100 m cruise) with the trajectory approach: its first
    # approach starts over unmapped ground and is handed to the climb-traverse-descend
    # fallback with the planner's reason; the retry after the failed verification is flown
    # along its trajectory to arrival, and the flight ends on safe ground with no collision.
    mission = apply_overrides(load_mission(MISSIONS / "mars_science.yaml"),
                              {"landing.approach.method": "trajectory"})
    result = fly(mission, seed=2)
    assert result.outcome == "landed" and result.summary["touchdown_safe"] is True
    assert result.summary["collisions"] == 0
    ends = [(e["new"], e["feedback"]) for e in result.events if e.get("kind") == "tree"
            and e.get("behaviour") == "FlyApproachTrajectory"
            and e.get("new") in ("SUCCESS", "FAILURE")]
    assert ends[0][0] == "FAILURE" and ends[0][1]
    assert ("SUCCESS", "arrived") in ends[1:]


def test_the_trajectory_keeps_the_clear_altitude_buffer_over_the_mapped_terrain():
    # A 3 m mound between the start and a site 10 m below the goal: with the default
    # margin (the mission's clear_altitude_buffer, 10 m) the trajectory goes around it,
    # keeping 10 m over every mapped top (+2 sigma) within the vehicle's radius; a mission
    # that asks for 2 m flies straight over it.
    from planning import clearance_grid

    m = _map_with_a_wall()
    m.top[:] = 0.1
    m.top[34:46, 30:50] = 3.0  # x = -3 .. 3 m, y = -5 .. 5 m
    settings = ApproachSettings(method="trajectory")
    guard = clearance_grid(m.top, m.variance, m.resolution, settings.vehicle_radius)
    for margin, over_the_mound in ((None, False), (2.0, True)):
        planner = MapApproachPlanner(
            m, settings.model_copy(update={"vertical_margin": margin}), default_margin=10.0)
        planned = planner.plan((-15.0, 0.0, 20.0), (15.0, 0.0, 10.0))
        assert not isinstance(planned, str), planned
        p = np.array([planned.state_at(float(t))[0]
                      for t in np.linspace(0.0, planned.duration, 600)])
        cells = np.floor(p[:, :2] / m.resolution).astype(int) - m.origin_index
        above = p[:, 2] - guard[cells[:, 0], cells[:, 1]]
        assert above.min() > (margin or 10.0)
        crossing = p[np.abs(p[:, 0]) < 3.0]
        assert (np.abs(crossing[:, 1]).min() < 5.0) == over_the_mound
