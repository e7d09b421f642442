"""Plain pymavlink on the vehicle's own links: greeted without speaking first, and a truthful
SYS_STATUS.

ArduPilot serves TCP (its SITL on 5760) and greets a new client at once. PX4 SITL serves no
TCP: it sends unasked to UDP 14540 (SDKs) and 14550 (ground stations), where a silent
listener hears it; the embedded PX4 personality does both (and TCP too).
"""

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
# What every multicopter autopilot has, uses and reports present, enabled and healthy once it
# is ready to arm.
ESSENTIAL = {
    "3D gyro": mavlink.MAV_SYS_STATUS_SENSOR_3D_GYRO,
    "3D accelerometer": mavlink.MAV_SYS_STATUS_SENSOR_3D_ACCEL,
    "absolute pressure": mavlink.MAV_SYS_STATUS_SENSOR_ABSOLUTE_PRESSURE,
    "GPS": mavlink.MAV_SYS_STATUS_SENSOR_GPS,
    "AHRS": mavlink.MAV_SYS_STATUS_AHRS,
}
# PX4 (its health report, v1.14 on) never marks its attitude estimate present: AHRS is only
# reported healthy.
HEALTHY_ONLY = {"px4": {"AHRS"}}
PREARM = mavlink.MAV_SYS_STATUS_PREARM_CHECK


def bit_names(mask: int) -> list[str]:
    names = mavlink.enums["MAV_SYS_STATUS_SENSOR"]
    return [names[1 << i].name for i in range(32) if mask >> i & 1 and (1 << i) in names]


def assert_autopilot_heartbeat(hb, autopilot: str, where: str) -> None:
    assert hb is not None, f"no HEARTBEAT {where}"
    assert hb.get_srcSystem() == 1 and hb.get_srcComponent() == 1, hb
    assert hb.autopilot == AUTOPILOT_ID[autopilot], hb
    assert hb.type == mavlink.MAV_TYPE_QUADROTOR, hb


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_a_silent_client_is_greeted_with_a_heartbeat(start_vehicle, autopilot):
    """Real ArduPilot sends HEARTBEAT to a new TCP client without waiting for it to speak; PX4
    SITL sends it unasked to the UDP ports of an SDK and a ground station."""
    vehicle = start_vehicle(autopilot)
    listeners = []
    if vehicle.tcp_port is not None:
        listeners.append((f"tcp:127.0.0.1:{vehicle.tcp_port}", "to a silent TCP client"))
    if autopilot == "px4":
        for port, who in ((vehicle.sdk_port, "an SDK"), (vehicle.gcs_port, "a ground station")):
            listeners.append((f"udpin:127.0.0.1:{port}", f"on UDP {port} ({who}), unasked"))
    assert listeners, vehicle.name
    for url, where in listeners:
        conn = mavutil.mavlink_connection(url, source_system=254)
        try:
            hb = conn.wait_heartbeat(timeout=vehicle.wall(5))
        finally:
            conn.close()
        assert_autopilot_heartbeat(hb, autopilot, f"from {vehicle.name} {where}")
    vehicle.alive()


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_sys_status_is_consistent(start_vehicle, autopilot):
    """SYS_STATUS says what is there, enabled and healthy without contradiction: nothing is
    enabled that is not present (PX4 also marks enabled what is required but missing, then
    unhealthy, e.g. an RC receiver SITL does not have: never absent, enabled and healthy), and
    once the vehicle is ready to arm every present and enabled sensor (the geofence included:
    unhealthy means breached) is healthy."""
    vehicle = start_vehicle(autopilot)
    if autopilot == "px4":  # where PX4 SITL sends its ground-station link
        gcs = Monitor(f"udpin:127.0.0.1:{vehicle.gcs_port}", heartbeat=True)
    else:
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
        if autopilot == "px4":
            extra &= s.onboard_control_sensors_health  # required and missing is unhealthy
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
            if name in HEALTHY_ONLY.get(autopilot, ()):
                assert health & bit, f"{name} not healthy: {s}"
                continue
            assert present & enabled & health & bit, f"{name} not present+enabled+healthy: {s}"
    vehicle.alive()
