"""Plain pymavlink on the vehicle's TCP port: greeted at once, and a truthful SYS_STATUS."""

from __future__ import annotations

import pytest
from conformance_support import Monitor
from pymavlink import mavutil

mavlink = mavutil.mavlink
pytestmark = pytest.mark.timeout(300)

AUTOPILOT_ID = {
    "ardupilot": mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA,
    "px4": mavlink.MAV_AUTOPILOT_PX4,
}
# What every multicopter autopilot has, uses and reports healthy once it is ready to arm.
ESSENTIAL = {
    "3D gyro": mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO,
    "3D accelerometer": mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL,
    "absolute pressure": mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE,
    "GPS": mavlink.MAV_SYS_STATUS_SENSOR_GPS,
    "AHRS": mavlink.MAV_SYS_STATUS_AHRS,
}
PREARM = mavlink.MAV_SYS_STATUS_PREARM_CHECK


def bit_names(mask: int) -> list[str]:
    names = mavlink.enums["MAV_SYS_STATUS_SENSOR"]
    return [names[1 << i].name for i in range(32) if mask >> i & 1 and (1 << i) in names]


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_tcp_client_is_greeted_with_a_heartbeat(start_vehicle, autopilot):
    """Real ArduPilot sends HEARTBEAT to a new TCP client without waiting for it to speak."""
    vehicle = start_vehicle(autopilot)
    conn = mavutil.mavlink_connection(f"tcp:127.0.0.1:{vehicle.tcp_port}", source_system=254)
    try:
        hb = conn.wait_heartbeat(timeout=vehicle.wall(5))
    finally:
        conn.close()
    assert hb is not None, f"no HEARTBEAT from {vehicle.name} to a silent TCP client"
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1, hb
    assert hb.autopilot == AUTOPILOT_ID[autopilot], hb
    assert hb.type == mavlink.MAV_TYPE_QUADROTOR, hb
    vehicle.alive()


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_sys_status_is_consistent(start_vehicle, autopilot):
    """SYS_STATUS says what is there, enabled and healthy without contradiction: nothing is
    enabled that is not present, and once the vehicle is ready to arm every present and
    enabled sensor (the geofence included: unhealthy means breached) is healthy."""
    vehicle = start_vehicle(autopilot)
    gcs = Monitor(f"tcp:127.0.0.1:{vehicle.tcp_port}", heartbeat=True)
    try:
        gcs.wait(lambda m: m.get("HEARTBEAT"), vehicle.wall(5), "HEARTBEAT")
        # What MAVProxy and QGroundControl ask of ArduPilot; PX4 streams without asking.
        gcs.conn.mav.request_data_stream_send(1, 1, mavlink.MAV_DATA_STREAM_ALL, 4, 1)
        gcs.conn.mav.command_long_send(
            1, 1, mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
            mavlink.MAVLINK_MSG_ID_SYS_STATUS, 200_000, 0, 0, 0, 0, 0,
        )  # fmt: skip
        seen = []

        def ready(m):
            s = m.get("SYS_STATUS")
            if s is not None and (not seen or seen[-1] is not s):
                seen.append(s)
            return s is not None and s.onboard_control_sensors_health & PREARM

        gcs.wait(ready, vehicle.wall(180), "SYS_STATUS with the pre-arm check passed")
        n = len(seen)
        gcs.wait(lambda m: ready(m) and len(seen) >= n + 5, vehicle.wall(10), "5 more SYS_STATUS")
    finally:
        gcs.close()

    for i, s in enumerate(seen):
        extra = s.onboard_control_sensors_enabled & ~s.onboard_control_sensors_present
        assert not extra, f"#{i}: enabled but not present: {bit_names(extra)} in {s}"
        assert 0 <= s.load <= 1000, s
        assert s.battery_remaining == -1 or 0 <= s.battery_remaining <= 100, s
    for s in seen[n - 1:]:
        present, enabled = s.onboard_control_sensors_present, s.onboard_control_sensors_enabled
        health = s.onboard_control_sensors_health
        failing = present & enabled & ~health
        assert s.voltage_battery > 0 and s.battery_remaining > 0, f"battery: {s}"
        assert not failing, f"ready to arm, yet unhealthy: {bit_names(failing)} in {s}"
        for name, bit in ESSENTIAL.items():
            if autopilot == "px4" and name == "3D accelerometer":
                continue  # PX4 (up to 1.15) leaves it out of "present"; MAVSDK allows that
            assert present & enabled & health & bit, f"{name} not present+enabled+healthy: {s}"
    vehicle.alive()
