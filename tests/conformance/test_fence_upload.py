"""The geofence a flight uploads, seen by a third party: the runner flies a mission with a
lat/lon geofence live against the vehicle (``lander sitl``, or ArduPilot's or PX4's own SITL
when CONFORMANCE_ARDUCOPTER / CONFORMANCE_PX4 name it), then plain pymavlink downloads the
vehicle's fence plan (MISSION_REQUEST_LIST with mission_type FENCE, each item by
MISSION_REQUEST_INT) and reads the fence parameters, as a ground station would."""

from __future__ import annotations

import pytest
import yaml
from conformance_support import HOME, Monitor, mavproxy_master, offset
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.cli.demo import mission_path
from autonomy.config import load_mission
from autonomy.runner import fly

pytestmark = pytest.mark.timeout(400)

FENCE = mavlink.MAV_MISSION_TYPE_FENCE
CEILING = 60.0
# (north, east) m of the corners about home, in order around the area; the demo's waypoints
# and sites are inside.
CORNERS = [(-20.0, -20.0), (-20.0, 70.0), (70.0, 70.0), (70.0, -20.0)]


def download_fence(mon: Monitor, vehicle) -> list:
    """The vehicle's fence plan, item by item (MAVLink's mission download)."""
    mon.conn.mav.mission_request_list_send(1, 1, FENCE)
    count = mon.wait(
        lambda m: (c := m.get("MISSION_COUNT")) is not None and c.mission_type == FENCE and c,
        vehicle.wall(10), "MISSION_COUNT of the fence plan")
    items = []
    for seq in range(count.count):
        mon.conn.mav.mission_request_int_send(1, 1, seq, FENCE)
        items.append(mon.wait(
            lambda m, seq=seq: next((i for i in m.kept["MISSION_ITEM_INT"]
                                     if i.seq == seq and i.mission_type == FENCE), None),
            vehicle.wall(10), f"fence item {seq}"))
    mon.conn.mav.mission_ack_send(1, 1, mavlink.MAV_MISSION_ACCEPTED, FENCE)
    return items


def read_param(mon: Monitor, vehicle, name: str) -> float:
    mon.conn.mav.param_request_read_send(1, 1, name.encode(), -1)
    answer = mon.wait(
        lambda m: next((p for p in m.kept["PARAM_VALUE"] if p.param_id == name), None),
        vehicle.wall(10), f"PARAM_VALUE {name}")
    return answer.param_value


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_the_fence_a_flight_uploaded_is_the_vehicles(autopilot, start_vehicle, tmp_path):
    vehicle = start_vehicle(autopilot)
    url = mavproxy_master(vehicle)
    corners = [offset(HOME[0], HOME[1], north, east) for north, east in CORNERS]
    data = yaml.safe_load(mission_path("demo.yaml").read_text())
    data["vehicle"]["connection"] = url
    data["home"] = {"lat": HOME[0], "lon": HOME[1], "alt": HOME[2]}
    # restore: false leaves the uploaded fence on the vehicle after landing, to download.
    data["geofence"] = {"polygon": [{"lat": lat, "lon": lon} for lat, lon in corners],
                        "max_altitude": CEILING, "restore": False}
    data.setdefault("landing", {})["failsafe_altitude"] = 50.0
    path = tmp_path / "fenced.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))

    result = fly(load_mission(path), out_dir=tmp_path / "out")
    upload = result.summary["geofence_upload"]
    assert upload["status"] == "accepted", upload
    assert result.summary["outcome"] == "landed_unjudged", result.summary["stop_reason"]
    vehicle.alive()

    mon = Monitor(url, heartbeat=True, keep=("MISSION_ITEM_INT", "PARAM_VALUE"))
    try:
        mon.wait(lambda m: m.get("HEARTBEAT"), vehicle.wall(10), "HEARTBEAT")
        items = download_fence(mon, vehicle)
        assert [i.command for i in items] == [
            mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * len(CORNERS)
        assert all(i.param1 == len(CORNERS) for i in items)
        # The user's lat/lon come back to MAVLink's 1e-7 degrees (the flight converted them
        # about the vehicle's home and back with the autopilot's own projection).
        for item, (lat, lon) in zip(items, corners, strict=True):
            assert abs(item.x - round(lat * 1e7)) <= 1 and abs(item.y - round(lon * 1e7)) <= 1
        if autopilot == "ardupilot":
            assert read_param(mon, vehicle, "FENCE_ALT_MAX") == CEILING
            assert read_param(mon, vehicle, "FENCE_TYPE") == 5  # polygon + max altitude
            mon.conn.mav.command_long_send(1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                                           mavlink.MAVLINK_MSG_ID_SYS_STATUS, 1e6, 0, 0, 0,
                                           0, 0)
            enabled = mon.wait(lambda m: m.get("SYS_STATUS"), vehicle.wall(10), "SYS_STATUS")
            # The autopilot's own word that its geofence is in force.
            assert enabled.onboard_control_sensors_enabled & mavlink.MAV_SYS_STATUS_GEOFENCE
        else:
            assert read_param(mon, vehicle, "GF_MAX_VER_DIST") == CEILING
    finally:
        mon.close()
