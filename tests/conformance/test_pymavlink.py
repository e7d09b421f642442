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

from sitl.copter import protocol_version
from sitl.copter.telemetry import build_hash

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


# A command no autopilot streams or sends (a ground station's message): what a request for a
# message the vehicle does not have looks like.
NOT_SENT = mavlink.MAVLINK_MSG_ID_COMMAND_LONG
# REQUEST_MESSAGE for such a message: ArduPilot fails it, PX4 denies it (SET_MESSAGE_INTERVAL
# fails on both, ArduPilot saying "No ap_message for mavlink id (76)").
NOT_SENT_REQUEST = {"ardupilot": mavlink.MAV_RESULT_FAILED, "px4": mavlink.MAV_RESULT_DENIED}
NO_SUCH_COMMAND = 54321  # in no dialect
# What QGroundControl asks for after AUTOPILOT_VERSION and PROTOCOL_VERSION (its
# InitialConnectStateMachine: standard modes, then component information with its fallback);
# not in pymavlink's dialect, hence the ids. An autopilot may send them or refuse them.
QGC_REQUESTS = {
    "AVAILABLE_MODES": 435,
    "COMPONENT_METADATA": 397,
    "COMPONENT_INFORMATION": 395,
}
REFUSALS = {mavlink.MAV_RESULT_DENIED, mavlink.MAV_RESULT_FAILED, mavlink.MAV_RESULT_UNSUPPORTED}


def git_hash_shown(autopilot: str, version) -> str:
    """The git hash as QGroundControl shows it (InitialConnectStateMachine): PX4's 8 bytes
    reversed as hex, ArduPilot's as text."""
    if autopilot == "px4":
        return bytes(reversed(version.flight_custom_version)).hex()
    return bytes(version.flight_custom_version).decode("ascii")


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_ground_station_connection_sequence(start_vehicle, autopilot, monkeypatch):
    """What QGroundControl asks of a vehicle it has just met, each answer checked: the
    autopilot's version (with its git hash) and capabilities, PROTOCOL_VERSION (PX4 sends it,
    ArduPilot has none), the standard modes and component information (sent, or refused:
    never ACCEPTED without the message), telemetry rates (the message interval protocol and
    the legacy data streams, whose EXTRA2 group is the HUD's VFR_HUD), the mission, fence and
    rally lists (empty ones answered with a count of 0, not silence), TIMESYNC, the full
    parameter list, and a COMMAND_ACK matched by command id for every command, including
    those the vehicle cannot do: a rate it cannot stream is refused, not ACCEPTED and never
    sent."""
    vehicle = start_vehicle(autopilot)
    if autopilot == "px4":  # where PX4 SITL sends its ground-station link
        gcs = Monitor(f"udpin:127.0.0.1:{vehicle.gcs_port}", heartbeat=True,
                      keep=("COMMAND_ACK", "MISSION_COUNT", "PARAM_VALUE", "TIMESYNC"))
    else:
        gcs = Monitor(f"tcp:127.0.0.1:{vehicle.tcp_port}", heartbeat=True,
                      keep=("COMMAND_ACK", "MISSION_COUNT", "PARAM_VALUE", "TIMESYNC"))
    w = vehicle.wall

    def command(cmd: int, *params: float):
        """Send COMMAND_LONG; the COMMAND_ACK for it (by command id)."""
        n = len([a for a in gcs.kept["COMMAND_ACK"] if a.command == cmd])
        p = list(params) + [0.0] * (7 - len(params))
        gcs.conn.mav.command_long_send(1, 1, cmd, 0, *p)
        acks = gcs.wait(
            lambda m: [a for a in m.kept["COMMAND_ACK"] if a.command == cmd][n:],
            w(5),
            f"COMMAND_ACK for command {cmd}",
        )
        return acks[0]

    try:
        gcs.wait(lambda m: m.get("HEARTBEAT"), w(5), "HEARTBEAT")
        # pymavlink switches to MAVLink 2 (a new encoder) on the first packet it reads; use
        # that one, as QGroundControl speaks MAVLink 2 (mission_type is a MAVLink 2 field).
        mav = gcs.conn.mav
        # pymavlink no longer defines PROTOCOL_VERSION: teach the dialect it now parses with
        # (mavutil switched to its MAVLink 2 module) the message.
        monkeypatch.setitem(mavutil.mavlink.mavlink_map, protocol_version.MSG_ID,
                            protocol_version.message_class())
        ack = command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED, ack
        version = gcs.wait(lambda m: m.get("AUTOPILOT_VERSION"), w(5), "AUTOPILOT_VERSION")
        assert version.capabilities & mavlink.MAV_PROTOCOL_CAPABILITY_MAVLINK2, version
        shown = git_hash_shown(autopilot, version)
        assert all(c in "0123456789abcdef" for c in shown) and len(shown) in (8, 16), version
        if not vehicle.real:  # the embedded SITL's hash is this checkout's
            assert build_hash().startswith(shown.rstrip("0")), (shown, build_hash())
        ack = command(mavlink.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED, ack

        ack = command(mavlink.MAV_CMD_REQUEST_MESSAGE, protocol_version.MSG_ID)
        if autopilot == "px4":
            assert ack.result == mavlink.MAV_RESULT_ACCEPTED, ack
            proto = gcs.wait(lambda m: m.get("PROTOCOL_VERSION"), w(5), "PROTOCOL_VERSION")
            assert proto.max_version >= 200 and proto.min_version <= proto.version, proto
            ack = command(mavlink.MAV_CMD_REQUEST_PROTOCOL_VERSION, 1)
            assert ack.result == mavlink.MAV_RESULT_ACCEPTED, ack
        else:  # no ap_message for it; no handler for the command
            assert ack.result == mavlink.MAV_RESULT_FAILED, ack
            ack = command(mavlink.MAV_CMD_REQUEST_PROTOCOL_VERSION, 1)
            assert ack.result == mavlink.MAV_RESULT_UNSUPPORTED, ack

        for name, msgid in QGC_REQUESTS.items():
            ack = command(mavlink.MAV_CMD_REQUEST_MESSAGE, msgid)
            if ack.result == mavlink.MAV_RESULT_ACCEPTED:
                gcs.wait(lambda m, i=msgid: [x for x in m.latest.values() if x.get_msgId() == i],
                         w(5), f"{name}, the request ACCEPTED")
            else:
                assert ack.result in REFUSALS, (name, ack)

        # Rates: what the vehicle has it streams; what it does not have it refuses.
        ack = command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL,
                      mavlink.MAVLINK_MSG_ID_ATTITUDE_QUATERNION, 100_000)
        assert ack.result == mavlink.MAV_RESULT_ACCEPTED, ack
        q = gcs.wait(lambda m: m.get("ATTITUDE_QUATERNION"), w(5), "ATTITUDE_QUATERNION")
        assert abs(q.q1**2 + q.q2**2 + q.q3**2 + q.q4**2 - 1.0) < 1e-3, q
        ack = command(mavlink.MAV_CMD_SET_MESSAGE_INTERVAL, NOT_SENT, 100_000)
        assert ack.result == mavlink.MAV_RESULT_FAILED, ack
        ack = command(mavlink.MAV_CMD_REQUEST_MESSAGE, NOT_SENT)
        assert ack.result == NOT_SENT_REQUEST[autopilot], ack
        ack = command(NO_SUCH_COMMAND, 1)
        assert ack.result == mavlink.MAV_RESULT_UNSUPPORTED, ack
        # QGroundControl asks ArduPilot for the legacy groups (PX4 ignores them and streams
        # VFR_HUD anyway).
        for stream in (mavlink.MAV_DATA_STREAM_EXTENDED_STATUS, mavlink.MAV_DATA_STREAM_POSITION,
                       mavlink.MAV_DATA_STREAM_EXTRA1, mavlink.MAV_DATA_STREAM_EXTRA2,
                       mavlink.MAV_DATA_STREAM_EXTRA3):
            mav.request_data_stream_send(1, 1, stream, 4, 1)
        gcs.wait(lambda m: m.get("VFR_HUD"), w(5), "VFR_HUD (data stream EXTRA2)")

        mav.timesync_send(0, 123_456_789)
        sync = gcs.wait(lambda m: m.kept["TIMESYNC"], w(5), "TIMESYNC answer")[0]
        assert sync.ts1 == 123_456_789 and sync.tc1 > 0, sync

        for mission_type in (mavlink.MAV_MISSION_TYPE_MISSION, mavlink.MAV_MISSION_TYPE_FENCE,
                             mavlink.MAV_MISSION_TYPE_RALLY):
            mav.mission_request_list_send(1, 1, mission_type)
            count = gcs.wait(
                lambda m, t=mission_type: [c for c in m.kept["MISSION_COUNT"]
                                           if c.mission_type == t],
                w(5),
                f"MISSION_COUNT of mission type {mission_type}",
            )[0]
            if mission_type != mavlink.MAV_MISSION_TYPE_MISSION:
                assert count.count == 0, count
            # End the download as a ground station does (nothing to fetch or home only).
            mav.mission_ack_send(1, 1, mavlink.MAV_MISSION_ACCEPTED, mission_type)

        mav.param_request_list_send(1, 1)

        def complete(m):
            values = m.kept["PARAM_VALUE"]
            return values and len({p.param_index for p in values}) >= values[0].param_count

        gcs.wait(complete, w(30), "every PARAM_VALUE of the list")
        values = gcs.kept["PARAM_VALUE"]
        total = values[0].param_count
        assert {p.param_count for p in values} == {total}, "param_count changed"
        assert {p.param_index for p in values} == set(range(total))
        assert len({p.param_id for p in values}) == total, "a name under two indices"
        assert all(1 <= p.param_type <= 10 for p in values), "a PARAM_VALUE without a type"
    finally:
        gcs.close()
    vehicle.alive()
