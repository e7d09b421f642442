"""The operating area uploaded to the autopilot (``geofence.upload``): lockstep ``lander fly``
flights on both personalities leave the embedded SITL holding the polygon and the ceiling
and enforcing them; the autopilot then answers a breach with its own fence action; a refused
upload fails preflight with one clear line; ``upload: false`` leaves the autopilot alone."""

from __future__ import annotations

import json

import pytest
import yaml
from pymavlink.dialects.v20 import ardupilotmega as mavlink

import autonomy.runner.run as runner
from autonomy.cli import main
from autonomy.cli.demo import mission_path
from autonomy.clock import SimClock
from autonomy.vehicle import connect, frames
from behaviors.ports import CommandStatus
from sitl.copter.mission import MissionItem

DEMO = mission_path("demo.yaml")
FENCE = mavlink.MAV_MISSION_TYPE_FENCE
POLYGON = [[-20.0, -20.0], [70.0, -20.0], [70.0, 70.0], [-20.0, 70.0]]
GEOFENCE = {"polygon": POLYGON, "max_altitude": 60}
DT = 0.05


def _mission(tmp_path, autopilot: str, geofence: dict, **changes) -> str:
    data = yaml.safe_load(DEMO.read_text())
    data["vehicle"]["autopilot"] = autopilot
    data["geofence"] = geofence
    data.setdefault("landing", {})["failsafe_altitude"] = 50.0  # under the ceiling
    for key, value in changes.items():
        data.setdefault(key, {}).update(value)
    path = tmp_path / f"fenced_{autopilot}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return str(path)


@pytest.fixture
def sitls(monkeypatch):
    """The embedded SITLs the flights of the test build (to look at them afterwards)."""
    built = []
    build = runner.build_sitl

    def keep(*args, **kwargs):
        sim = build(*args, **kwargs)
        built.append(sim)
        return sim

    monkeypatch.setattr(runner, "build_sitl", keep)
    return built


def _fly(path: str, out) -> int:
    return main(["fly", path, "--out", str(out)])


def _events(out, event: str) -> list[dict]:
    lines = (out / "events.jsonl").read_text().splitlines()
    return [e for e in map(json.loads, lines) if e.get("event") == event]


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_flight_leaves_the_autopilot_holding_and_enforcing_the_area(
        autopilot, tmp_path, sitls, capsys):
    # restore: false keeps the mission's fence on the vehicle after the flight, to look at.
    out = tmp_path / "out"
    assert _fly(_mission(tmp_path, autopilot, {**GEOFENCE, "restore": False}), out) == 0
    console = capsys.readouterr().out
    action = {"ardupilot": "FENCE_ACTION 1 (RTL or land)", "px4": "GF_ACTION 2 (Hold)"}
    assert ("geofence uploaded to the autopilot: inclusion polygon of 4 vertices, ceiling "
            "60 m above home") in console
    assert f"{action[autopilot]} on a breach\n" in console
    [event] = _events(out, "geofence_uploaded")
    assert (event["vertices"], event["max_altitude"], event["status"]) == (4, 60.0, "accepted")
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "landed"
    assert summary["geofence_upload"]["status"] == "accepted"
    preflight_end = next(e["t"] for e in map(json.loads, (out / "events.jsonl").read_text()
                                              .splitlines()) if e.get("phase") == "takeoff")
    assert event["t"] <= preflight_end, "uploaded before takeoff"

    [sim] = sitls
    ap = sim.autopilot
    plan = ap.mission.plans[FENCE]
    assert [item.command for item in plan] == [
        mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * 4
    assert all(item.param1 == 4 for item in plan)
    # The SITL places the vertices where the mission has them (its own projection).
    [zone] = ap.fence.zones().inclusion
    hx, hy = ap.home_xy
    assert zone.ravel().tolist() == pytest.approx(
        [v for x, y in POLYGON for v in (x + hx, y + hy)], abs=0.05)
    if autopilot == "ardupilot":
        assert ap.params.stored("FENCE_ALT_MAX") == 60.0
        assert ap.fence.enabled() == 5, "polygon and max altitude enforced (FENCE_TYPE bits)"
    else:
        assert ap.params.stored("GF_MAX_VER_DIST") == 60.0
        assert ap.params.stored("GF_ACTION") != 0, "PX4 enforces a fence plan with an action"


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_after_the_flight_the_vehicles_own_fence_is_put_back(autopilot, tmp_path, monkeypatch,
                                                             capsys):
    # The vehicle holds a no-fly circle of its operator's; the flight uploads the area (with
    # the circle kept), lands, and then puts back the circle alone, the parameters it changed
    # and (ArduPilot) the fences off as FENCE_ENABLE 0 says.
    built = []
    build = runner.build_sitl

    def with_operators_fence(*args, **kwargs):
        sim = build(*args, **kwargs)
        lat, lon = sim.autopilot.home_geo[:2]
        sim.autopilot.mission.replace(FENCE, [MissionItem(
            mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION, mavlink.MAV_FRAME_GLOBAL, param1=15.0,
            x=lat - 0.002, y=lon)])
        built.append(sim)
        return sim

    monkeypatch.setattr(runner, "build_sitl", with_operators_fence)
    out = tmp_path / "out"
    assert _fly(_mission(tmp_path, autopilot, GEOFENCE), out) == 0
    console = capsys.readouterr().out
    ceiling = {"ardupilot": "FENCE_ALT_MAX 100, FENCE_TYPE 7, fences disabled as FENCE_ENABLE",
               "px4": "GF_MAX_VER_DIST 0"}[autopilot]
    line = ("the vehicle's geofence restored on the autopilot: its fence plan (1 zone), "
            f"{ceiling}")
    assert line in console
    assert _events(out, "geofence_restored")[0]["text"] == line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["geofence_upload"]["restored"] == line
    assert "kept the vehicle's 1 exclusion zone" in summary["geofence_upload"]["text"]
    ap = built[0].autopilot
    assert [item.command for item in ap.mission.plans[FENCE]] == [
        mavlink.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION]
    if autopilot == "ardupilot":
        assert (ap.params.stored("FENCE_ALT_MAX"), ap.params.stored("FENCE_TYPE")) == (100, 7)
        assert not ap.fence.enabled()
    else:
        assert ap.params.stored("GF_MAX_VER_DIST") == 0


class Lockstep:
    """A driver connected to an embedded SITL, stepped together on one simulated clock."""

    def __init__(self, autopilot: str) -> None:
        self.clock = SimClock()
        self.vehicle = connect(f"sim://{autopilot}", self.clock)
        self.sim = self.vehicle.sitl

    def until(self, condition, timeout: float, what: str):
        end = self.clock.now() + timeout
        while self.clock.now() < end:
            self.sim.step(DT)
            self.clock.advance(DT)
            state = self.vehicle.poll()
            if condition(state):
                return state
        raise AssertionError(f"{what}: not in {timeout} s; {self.vehicle.state}")

    def upload_and_take_off(self, polygon, max_altitude: float) -> None:
        self.until(lambda s: s.prearm_ok and s.position_estimate, 60, "ready")
        upload = self.vehicle.upload_fence(polygon, max_altitude)
        self.until(lambda s: upload.done, 30, "upload")
        assert upload.status is CommandStatus.ACCEPTED, upload.reason
        takeoff = self.vehicle.takeoff(10.0)
        self.until(lambda s: s.position is not None and s.position[2] > 9.0, 60, "takeoff")
        assert takeoff.status is CommandStatus.ACCEPTED


@pytest.fixture(params=[("ardupilot", "RTL"), ("px4", "AUTO.LOITER")],
                ids=["ardupilot", "px4"])
def lockstep(request):
    """(a Lockstep, the mode its autopilot's breach action puts it in: ArduPilot
    FENCE_ACTION 1, RTL; PX4 GF_ACTION 2, Hold)."""
    autopilot, action_mode = request.param
    rig = Lockstep(autopilot)
    try:
        yield rig, action_mode
    finally:
        rig.vehicle.close()


def test_the_autopilot_answers_a_breach_of_the_uploaded_fence(lockstep):
    # Flown past the edge at a constant velocity (a position target beyond an enabled fence
    # is refused by ArduPilot): the autopilot's own action takes over.
    rig, action_mode = lockstep
    rig.upload_and_take_off([(-30.0, -30.0), (30.0, -30.0), (30.0, 30.0), (-30.0, 30.0)],
                            40.0)
    rig.vehicle.set_velocity(5.0, 0.0, 0.0)
    state = rig.until(lambda s: s.mode == action_mode, 60, "the autopilot's fence action")
    assert 25.0 < state.position[0] < 45.0, "it acted at the edge (x = 30 m)"
    assert rig.sim.autopilot.fence.breach_count >= 1


def test_a_no_fly_zone_on_the_vehicle_is_still_enforced_after_the_upload(lockstep):
    # The operator put a no-fly square 40-60 m east of home on the vehicle. The flight's
    # operating area (100 m square) covers it; the upload keeps the zone, and the autopilot
    # acts when the vehicle flies into it.
    rig, action_mode = lockstep
    ap = rig.sim.autopilot
    lat0, lon0 = ap.home_geo[:2]
    no_fly = [frames.local_to_geodetic(x, y, lat0, lon0, rig.vehicle.autopilot)
              for x, y in [(40.0, -10.0), (60.0, -10.0), (60.0, 10.0), (40.0, 10.0)]]
    ap.mission.replace(FENCE, [
        MissionItem(mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION, mavlink.MAV_FRAME_GLOBAL,
                    param1=4.0, x=lat, y=lon) for lat, lon in no_fly])
    rig.upload_and_take_off([(-100.0, -100.0), (100.0, -100.0), (100.0, 100.0),
                             (-100.0, 100.0)], 40.0)
    assert rig.vehicle.fence_upload.vehicle_fence == "kept the vehicle's 1 exclusion zone"
    commands = [item.command for item in ap.mission.plans[FENCE]]
    assert commands == ([mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * 4
                        + [mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION] * 4)
    rig.vehicle.set_velocity(5.0, 0.0, 0.0)
    state = rig.until(lambda s: s.mode == action_mode, 60, "the autopilot's fence action")
    assert 35.0 < state.position[0] < 55.0, "it acted at the no-fly zone (x = 40 m)"


def test_a_refused_upload_fails_preflight_with_one_clear_line(tmp_path, sitls, capsys):
    # The SITL holds at most 3 items per plan: it answers the 4-vertex fence's MISSION_COUNT
    # with MAV_MISSION_NO_SPACE, as an autopilot with FENCE_TOTAL too small does.
    out = tmp_path / "out"
    path = _mission(tmp_path, "ardupilot", GEOFENCE, sitl={"mission_capacity": 3})
    assert _fly(path, out) == 1
    console = capsys.readouterr().out
    line = ("geofence upload failed (denied): fence plan: the autopilot answered MISSION_ACK "
            "MAV_MISSION_NO_SPACE")
    assert line in console
    assert "Traceback" not in console
    summary = json.loads((out / "summary.json").read_text())
    assert summary["outcome"] == "aborted"
    assert summary["failure_reason"].startswith("Preflight: geofence not uploaded (denied)")
    assert summary["geofence_upload"]["status"] == "denied"
    assert _events(out, "geofence_refused")[0]["text"] == line
    assert not sitls[0].autopilot.armed and not sitls[0].autopilot.fence.enabled()


def test_upload_false_leaves_the_autopilots_fence_alone(tmp_path, sitls, capsys):
    out = tmp_path / "out"
    assert _fly(_mission(tmp_path, "ardupilot", {**GEOFENCE, "upload": False}), out) == 0
    assert "geofence upload" not in capsys.readouterr().out
    summary = json.loads((out / "summary.json").read_text())
    assert "geofence_upload" not in summary and summary["geofence"]
    ap = sitls[0].autopilot
    assert ap.mission.plans[FENCE] == [] and not ap.fence.enabled()
    assert ap.params.stored("FENCE_ALT_MAX") == 100.0  # the autopilot's default, untouched


def test_a_bad_upload_setting_is_one_line_naming_the_field(tmp_path, capsys):
    path = _mission(tmp_path, "ardupilot", {**GEOFENCE, "upload": "sometimes"})
    assert main(["validate", path]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("lander validate: error: ")
    assert line.endswith(": geofence.upload: must be true or false (got 'sometimes')")
