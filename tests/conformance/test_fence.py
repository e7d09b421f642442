"""The geofence, flown with plain pymavlink: an inclusion polygon around home uploaded as the
fence plan, the vehicle out of it when the fence comes into force, and the autopilot's answer.

Both autopilots check where the vehicle is, however it got there, so the breach is made the
way that works on the real ones too: ArduPilot flies out with FENCE_ENABLE 0 and is then
enabled (a guided target beyond an enabled fence is refused, and AVOID_ENABLE would stop it at
the fence); PX4 flies out before the fence plan arrives. ArduPilot (FENCE_ACTION 1) returns,
says "Polygon fence breached", reports the breach in FENCE_STATUS and SYS_STATUS, clears it on
the way home and lands; PX4 with GF_ACTION 3 (Return) says "Geofence violation: ..." and
returns.
"""

from __future__ import annotations

import struct
import time

import pytest
from conformance_support import HOME, Monitor, distance, offset
from pymavlink.dialects.v20 import ardupilotmega as mavlink

pytestmark = pytest.mark.timeout(400)

FENCE = mavlink.MAV_MISSION_TYPE_FENCE
GEOFENCE = mavlink.MAV_SYS_STATUS_GEOFENCE
RTL_MODE = {"ardupilot": 6, "px4": (4 << 16) | (5 << 24)}
GUIDED = 4
HALF = 30.0  # m: the fence is a square this far either side of home
OUT = 55.0  # m east of home, where the vehicle goes first


def command(mon: Monitor, cmd: int, *params: float) -> None:
    p = list(params) + [0.0] * (7 - len(params))
    mon.conn.mav.command_long_send(1, 1, cmd, 0, *p)


def set_param(mon: Monitor, autopilot: str, name: str, value: int, kind: int) -> None:
    """PARAM_SET as each autopilot encodes an integer (PX4: its bytes in the float)."""
    wire = struct.unpack("<f", struct.pack("<i", value))[0] if autopilot == "px4" else value
    mon.conn.mav.param_set_send(1, 1, name.encode(), wire, kind)


def upload_fence(mon: Monitor, vehicle) -> None:
    lat, lon = HOME[0], HOME[1]
    corners = [(-HALF, -HALF), (-HALF, HALF), (HALF, HALF), (HALF, -HALF)]
    items = []
    for seq, (north, east) in enumerate(corners):
        vlat, vlon = offset(lat, lon, north, east)
        items.append(mavlink.MAVLink_mission_item_int_message(
            1, 1, seq, mavlink.MAV_FRAME_GLOBAL, mavlink.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            0, 1, len(corners), 0, 0, 0, int(vlat * 1e7), int(vlon * 1e7), 0, FENCE,
        ))  # fmt: skip
    mon.conn.mav.mission_count_send(1, 1, len(items), FENCE)
    for seq, item in enumerate(items):
        def asked(m, seq=seq):
            return any(
                r is not None and r.mission_type == FENCE and r.seq == seq
                for r in (m.get("MISSION_REQUEST_INT"), m.get("MISSION_REQUEST"))
            )

        mon.wait(asked, vehicle.wall(10), f"request for fence item {seq}")
        mon.conn.mav.send(item)
    ack = mon.wait(
        lambda m: (a := m.get("MISSION_ACK")) is not None and a.mission_type == FENCE and a,
        vehicle.wall(10), "fence upload ACK",
    )
    assert ack.type == mavlink.MAV_MISSION_ACCEPTED, ack


def east_of_home(mon: Monitor) -> float:
    if not mon.positions:
        return 0.0
    lat, lon, _ = mon.positions[-1]
    return distance(HOME[0], HOME[1], lat, lon)


def take_off(mon: Monitor, vehicle, autopilot: str) -> None:
    """Arm and climb, retrying while the estimator settles."""
    end = time.monotonic() + vehicle.wall(120)
    while not mon.armed():
        assert time.monotonic() < end, f"never armed: {mon.summary()}"
        if autopilot == "ardupilot":
            command(mon, mavlink.MAV_CMD_DO_SET_MODE, 1, GUIDED)
        command(mon, mavlink.MAV_CMD_COMPONENT_ARM_DISARM, 1)
        time.sleep(vehicle.sim_sleep(2.0))
    if autopilot == "ardupilot":
        command(mon, mavlink.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
    else:
        command(mon, mavlink.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, float("nan"), float("nan"),
                float("nan"), HOME[2] + 10)
    mon.wait(lambda m: m.positions and m.positions[-1][2] > 8.0, vehicle.wall(60), "climb")


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_fence_breach_returns_the_vehicle(start_vehicle, autopilot):
    vehicle = start_vehicle(autopilot)
    if autopilot == "px4":
        url = f"udpin:127.0.0.1:{vehicle.sdk_port}"
    else:
        url = f"tcp:127.0.0.1:{vehicle.tcp_port}"
    mon = Monitor(url, heartbeat=True, keep=("SYS_STATUS", "FENCE_STATUS"))
    # The fence plan needs MAVLink 2's mission_type, which mavutil's default dialect (MAVLink
    # 1) neither sends nor reads: this connection speaks the MAVLink 2 dialect.
    mon.conn.mav = mavlink.MAVLink(mon.conn, srcSystem=254, srcComponent=190)
    mon.conn.mav.robust_parsing = True
    try:
        mon.wait(lambda m: m.get("HEARTBEAT"), vehicle.wall(10), "HEARTBEAT")
        if autopilot == "ardupilot":
            mon.conn.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_ALL, 4, 1)
            upload_fence(mon, vehicle)  # not in force while FENCE_ENABLE is 0
        else:
            set_param(mon, autopilot, "GF_ACTION", 3, mavlink.MAV_PARAM_TYPE_INT32)  # Return
            mon.wait(lambda m: (p := m.get("PARAM_VALUE")) and p.param_id == "GF_ACTION",
                     vehicle.wall(10), "GF_ACTION set")
        take_off(mon, vehicle, autopilot)
        lat, lon = offset(HOME[0], HOME[1], 0.0, OUT)
        mon.conn.mav.command_int_send(
            1, 1, mavlink.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mavlink.MAV_CMD_DO_REPOSITION, 0, 0,
            -1, mavlink.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, float("nan"),
            int(lat * 1e7), int(lon * 1e7), 10,
        )  # fmt: skip
        mon.wait(lambda m: east_of_home(m) > OUT - 3.0, vehicle.wall(60), "out of the fence")
        texts_before = len(mon.texts)
        if autopilot == "ardupilot":
            set_param(mon, autopilot, "FENCE_ENABLE", 1, mavlink.MAV_PARAM_TYPE_INT8)
        else:
            upload_fence(mon, vehicle)
        mon.wait(lambda m: m.custom_mode() == RTL_MODE[autopilot], vehicle.wall(20),
                 "the return the fence orders")
        said = mon.wait(lambda m: [t for t in m.texts[texts_before:] if "fence" in t.lower()],
                        vehicle.wall(10), "a STATUSTEXT about the fence")
        if autopilot == "px4":
            assert said[0].startswith("Geofence violation"), said
            mon.wait(lambda m: not m.armed(), vehicle.wall(120), "landed and disarmed at home")
            return
        assert "Polygon fence breached" in said, said
        status = mon.wait(lambda m: (s := m.get("FENCE_STATUS")) and s.breach_status and s,
                          vehicle.wall(10), "FENCE_STATUS breached")
        assert status.breach_type == mavlink.FENCE_BREACH_BOUNDARY and status.breach_count >= 1
        sys_status = mon.wait(
            lambda m: (s := m.get("SYS_STATUS")) and not s.onboard_control_sensors_health
            & GEOFENCE and s, vehicle.wall(10), "SYS_STATUS with the geofence unhealthy",
        )
        assert sys_status.onboard_control_sensors_present & GEOFENCE
        assert sys_status.onboard_control_sensors_enabled & GEOFENCE
        mon.wait(lambda m: "Fence breach cleared" in m.texts, vehicle.wall(60),
                 "breach cleared on the way home")
        mon.wait(lambda m: not m.armed(), vehicle.wall(120), "landed and disarmed at home")
        assert east_of_home(mon) < 3.0
        assert not mon.get("FENCE_STATUS").breach_status
    finally:
        mon.close()
    vehicle.alive()
