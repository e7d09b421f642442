"""What ground stations and SDKs send the embedded SITL, in both personalities: NaN and odd
values, the parameter and mission protocols, AUTO missions, global targets, repositioning,
speed changes, signing. Driven over the in-memory link by a plain pymavlink client."""

from __future__ import annotations

import math
import struct

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl
from sitl.copter.gcs import MiniGcs
from sitl.copter.geo import LocalToGlobal

DT = 0.05
NAN = math.nan
C = mavlink
ARDUPILOT_GUIDED, ARDUPILOT_AUTO, ARDUPILOT_LOITER = 4, 3, 5
PX4_MISSION = (4 << 16) | (4 << 24)
PX4_LOITER = (4 << 16) | (3 << 24)
PX4_OFFBOARD = 6 << 16


def connect(autopilot: str = "ardupilot", **kwargs) -> tuple[Sitl, MiniGcs]:
    sim = Sitl(autopilot=autopilot, **kwargs)
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)
    gcs.heartbeat()
    return sim, gcs


def run(sim: Sitl, gcs: MiniGcs, seconds: float, until=None) -> bool:
    end = sim.time + seconds
    while sim.time < end - 1e-9:
        sim.step(DT)
        gcs.poll()
        if until is not None and until():
            return True
    return until is None


def settle(sim, gcs) -> None:
    run(sim, gcs, sim.settings.arming_settle_time + 0.1)


def latlon(sim: Sitl, east: float, north: float) -> tuple[float, float]:
    home = sim.settings.home
    return LocalToGlobal(home.lat, home.lon)(east, north)


def airborne(sim, gcs, altitude=10.0) -> None:
    settle(sim, gcs)
    if sim.personality == "px4":
        gcs.arm()
        gcs.command(C.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, NAN, NAN, NAN,
                    sim.settings.home.alt + altitude)
    else:
        gcs.set_mode(ARDUPILOT_GUIDED)
        gcs.arm()
        gcs.takeoff(altitude)
    assert run(sim, gcs, 40, until=lambda: sim.truth.position[2] > altitude - 0.35)


def last_ack(gcs: MiniGcs, command: int) -> int:
    acks = gcs.acks(command)
    assert acks, f"no COMMAND_ACK for {command}"
    return acks[-1]


# ----------------------------------------------------------------------------- commands
COMMANDS = sorted(
    c for c in C.enums["MAV_CMD"]
    if c not in (C.MAV_CMD_ENUM_END, C.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN)
)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_every_command_with_nan_and_extreme_parameters_gets_an_ack(autopilot):
    sim, gcs = connect(autopilot)
    settle(sim, gcs)
    odd = (NAN, math.inf, -math.inf, 3.4e38, -3.4e38, -1.0, 0.0)
    for command in COMMANDS:
        for value in odd:
            gcs.mav.command_long_send(1, 1, command, 0, *([value] * 7))
            gcs.mav.command_int_send(1, 1, C.MAV_FRAME_GLOBAL_INT, command, 0, 0,
                                     *([value] * 4), 2**31 - 1, -(2**31), value)
        sim.step(DT)
        gcs.poll()
    assert sim.server.handler_errors == 0
    acked = {m.command for m in gcs.of_type("COMMAND_ACK")}
    assert acked >= set(COMMANDS)
    run(sim, gcs, 2)  # and it keeps flying the model
    assert sim.truth.time > sim.settings.arming_settle_time + 2


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_arm_with_nan_in_unused_parameters_arms(autopilot):
    # MAVSDK and QGroundControl send NaN in the parameters a command does not use.
    sim, gcs = connect(autopilot)
    settle(sim, gcs)
    gcs.mav.command_long_send(1, 1, C.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, *([NAN] * 6))
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_COMPONENT_ARM_DISARM) == C.MAV_RESULT_ACCEPTED
    assert sim.truth.armed


def test_unknown_command_is_unsupported():
    sim, gcs = connect()
    gcs.command(C.MAV_CMD_DO_SET_SERVO, 9, 1500)
    gcs.command(54321)  # not a MAV_CMD at all
    run(sim, gcs, 0.1)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_SERVO) == C.MAV_RESULT_UNSUPPORTED
    assert last_ack(gcs, 54321) == C.MAV_RESULT_UNSUPPORTED


def test_refusal_text_follows_the_ack_in_the_same_step():
    sim, gcs = connect()
    gcs.arm()  # not settled yet: refused with a PreArm reason
    sim.step(DT)
    msgs = gcs.poll()
    names = [m.get_type() for m in msgs if m.get_type() in ("COMMAND_ACK", "STATUSTEXT")]
    assert names[:2] == ["COMMAND_ACK", "STATUSTEXT"]
    assert msgs[[m.get_type() for m in msgs].index("STATUSTEXT")].text.startswith("PreArm")


@pytest.mark.parametrize("autopilot, capability", [
    ("ardupilot", C.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_C_CAST),
    ("px4", C.MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE),
])
def test_autopilot_version_claims_what_the_simulator_does(autopilot, capability):
    sim, gcs = connect(autopilot)
    gcs.command(C.MAV_CMD_REQUEST_MESSAGE, C.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    run(sim, gcs, 0.1)
    caps = gcs.last["AUTOPILOT_VERSION"].capabilities
    for claimed in (capability, C.MAV_PROTOCOL_CAPABILITY_MISSION_INT,
                    C.MAV_PROTOCOL_CAPABILITY_COMMAND_INT,
                    C.MAV_PROTOCOL_CAPABILITY_SET_POSITION_TARGET_GLOBAL_INT):
        assert caps & claimed
    for not_done in (C.MAV_PROTOCOL_CAPABILITY_FTP, C.MAV_PROTOCOL_CAPABILITY_TERRAIN,
                     C.MAV_PROTOCOL_CAPABILITY_SET_ATTITUDE_TARGET,
                     C.MAV_PROTOCOL_CAPABILITY_FLIGHT_TERMINATION):
        assert not caps & not_done


def test_no_fence_breach_or_sensor_failure_is_reported_when_settled():
    sim, gcs = connect()
    gcs.set_interval(C.MAVLINK_MSG_ID_SYS_STATUS, 2)
    settle(sim, gcs)
    run(sim, gcs, 1)
    status = gcs.last["SYS_STATUS"]
    present, health = status.onboard_control_sensors_present, status.onboard_control_sensors_health
    assert health & C.MAV_SYS_STATUS_GEOFENCE  # MAVProxy reads a missing bit as a breach
    assert present & health == present  # everything present is healthy


def test_timesync_request_is_answered_with_our_time():
    sim, gcs = connect()
    run(sim, gcs, 1)
    gcs.mav.timesync_send(0, 123456789)
    run(sim, gcs, 0.1)
    reply = gcs.last["TIMESYNC"]
    assert reply.ts1 == 123456789 and reply.tc1 == pytest.approx(sim.time * 1e9, abs=2e8)


# ----------------------------------------------------------------------------- parameters
@pytest.mark.parametrize("autopilot, count", [("ardupilot", 33), ("px4", 23)])
def test_parameter_list_has_count_index_and_type(autopilot, count):
    sim, gcs = connect(autopilot)
    gcs.param_request_list()
    run(sim, gcs, 1)
    values = gcs.of_type("PARAM_VALUE")
    assert len(values) == count
    assert sorted(v.param_index for v in values) == list(range(count))
    assert {v.param_count for v in values} == {count}
    assert len({v.param_id for v in values}) == count


def test_ardupilot_parameter_set_changes_the_flight_speed():
    sim, gcs = connect()
    gcs.param_read("WPNAV_SPEED")
    run(sim, gcs, 0.1)
    assert gcs.params()["WPNAV_SPEED"] == 1000.0  # cm/s, as ArduPilot's
    assert gcs.last["PARAM_VALUE"].param_type == C.MAV_PARAM_TYPE_REAL32
    gcs.param_set("WPNAV_SPEED", 400.0, C.MAV_PARAM_TYPE_REAL32)
    run(sim, gcs, 0.1)
    assert gcs.params()["WPNAV_SPEED"] == 400.0
    airborne(sim, gcs)
    gcs.goto_ned(100.0, 0.0, -10.0)
    run(sim, gcs, 20)
    speed = math.hypot(*sim.truth.velocity[:2])
    assert speed == pytest.approx(4.0, abs=0.1)


def test_refused_parameter_set_answers_with_the_value_in_force():
    sim, gcs = connect()
    gcs.param_set("LAND_SPEED", -50, C.MAV_PARAM_TYPE_INT16)  # the settings refuse it
    gcs.param_set("WPNAV_SPEED", NAN, C.MAV_PARAM_TYPE_REAL32)
    gcs.param_set("NO_SUCH_PARAM", 1.0, C.MAV_PARAM_TYPE_REAL32)
    run(sim, gcs, 0.1)
    params = gcs.params()
    assert params["LAND_SPEED"] == 50.0 and params["WPNAV_SPEED"] == 1000.0
    assert "NO_SUCH_PARAM" not in params
    assert sim.settings.land_speed == 0.5


def test_px4_parameters_read_by_index_and_ints_travel_bytewise():
    sim, gcs = connect("px4")
    gcs.param_set("MIS_TAKEOFF_ALT", 7.5, C.MAV_PARAM_TYPE_REAL32)
    as_float = struct.unpack("<f", struct.pack("<i", 10016))[0]
    gcs.param_set("SYS_AUTOSTART", as_float, C.MAV_PARAM_TYPE_INT32)
    run(sim, gcs, 0.1)
    assert sim.settings.px4_takeoff_altitude == 7.5
    gcs.param_read(index=1)  # SYS_AUTOSTART
    run(sim, gcs, 0.1)
    msg = gcs.last["PARAM_VALUE"]
    assert msg.param_id == "SYS_AUTOSTART" and msg.param_type == C.MAV_PARAM_TYPE_INT32
    assert struct.unpack("<i", struct.pack("<f", msg.param_value))[0] == 10016
    # A NaN take-off altitude takes MIS_TAKEOFF_ALT, as PX4 does.
    settle(sim, gcs)
    gcs.arm()
    gcs.command(C.MAV_CMD_NAV_TAKEOFF, -1, 0, 0, NAN, NAN, NAN, NAN)
    assert run(sim, gcs, 30, until=lambda: sim.truth.mode == "AUTO.LOITER")
    assert sim.truth.position[2] == pytest.approx(7.5, abs=0.35)


# ----------------------------------------------------------------------------- missions
def square_mission(sim: Sitl, gcs: MiniGcs, home_first: bool) -> list:
    items = []
    if home_first:  # ArduPilot's item 0 is home
        home = sim.settings.home
        items.append(gcs.mission_item(0, C.MAV_CMD_NAV_WAYPOINT, home.lat, home.lon, home.alt,
                                      frame=C.MAV_FRAME_GLOBAL_INT))
    items.append(gcs.mission_item(len(items), C.MAV_CMD_NAV_TAKEOFF, alt=12.0))
    for east, north in ((30.0, 0.0), (30.0, 30.0)):
        items.append(gcs.mission_item(len(items), C.MAV_CMD_NAV_WAYPOINT,
                                      *latlon(sim, east, north), 12.0))
    items.append(gcs.mission_item(len(items), C.MAV_CMD_DO_CHANGE_SPEED,
                                  params=(1.0, 4.0, -1.0, 0.0), frame=C.MAV_FRAME_MISSION))
    items.append(gcs.mission_item(len(items), C.MAV_CMD_NAV_LAND, *latlon(sim, 0.0, 30.0)))
    return items


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mission_upload_then_download_gives_it_back(autopilot):
    sim, gcs = connect(autopilot)
    items = square_mission(sim, gcs, home_first=autopilot == "ardupilot")
    gcs.upload_mission(items)
    assert run(sim, gcs, 5, until=lambda: "MISSION_ACK" in gcs.last)
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_ACCEPTED
    gcs.download_mission()
    assert run(sim, gcs, 5, until=lambda: len(gcs.downloaded) == len(items))
    first = 1 if autopilot == "ardupilot" else 0
    # ArduPilot keeps the altitude reference, not the frame: *_INT frames come back as their
    # float twins (GLOBAL_RELATIVE_ALT_INT -> GLOBAL_RELATIVE_ALT), as on the real autopilot.
    twin = {C.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT: C.MAV_FRAME_GLOBAL_RELATIVE_ALT}
    for sent, got in zip(items[first:], gcs.downloaded[first:], strict=True):
        frame = twin.get(sent.frame, sent.frame) if autopilot == "ardupilot" else sent.frame
        assert got.frame == frame
        for field in ("seq", "command", "param1", "param2", "x", "y", "z"):
            assert getattr(got, field) == pytest.approx(getattr(sent, field)), field


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_do_land_start_flies_the_landing_sequence(autopilot):
    """MAV_CMD_DO_LAND_START (MAVProxy's `land`): FAILED without a landing sequence, as
    ArduPilot answers; with one, the mission mode from its DO_LAND_START item to the landing."""
    sim, gcs = connect(autopilot)
    airborne(sim, gcs)
    gcs.command(C.MAV_CMD_DO_LAND_START)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_LAND_START) == C.MAV_RESULT_FAILED
    items = square_mission(sim, gcs, home_first=autopilot == "ardupilot")
    land_start = len(items) - 1  # before the NAV_LAND, after the waypoints
    items.insert(land_start, gcs.mission_item(land_start, C.MAV_CMD_DO_LAND_START,
                                              *latlon(sim, 0.0, 30.0)))
    items[-1].seq = len(items) - 1
    gcs.upload_mission(items)
    assert run(sim, gcs, 5, until=lambda: "MISSION_ACK" in gcs.last)
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_ACCEPTED
    gcs.command(C.MAV_CMD_DO_LAND_START)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_LAND_START) == C.MAV_RESULT_ACCEPTED
    assert sim.truth.mode == ("AUTO" if autopilot == "ardupilot" else "AUTO.MISSION")
    track = []

    def landed() -> bool:
        track.append(sim.truth.position[:2])
        return not sim.truth.armed

    assert run(sim, gcs, 120, until=landed)
    # Straight to the landing: the waypoint east of home (30, 0) is skipped.
    assert min(math.hypot(e - 30.0, n) for e, n in track) > 10.0
    east, north = sim.truth.position[:2]
    assert math.hypot(east - 0.0, north - 30.0) < 1.0


def test_ardupilot_reports_home_as_item_zero_even_without_a_mission():
    sim, gcs = connect()
    gcs.download_mission()
    assert run(sim, gcs, 2, until=lambda: len(gcs.downloaded) == 1)
    home = gcs.downloaded[0]
    assert home.seq == 0 and home.command == C.MAV_CMD_NAV_WAYPOINT
    assert home.x == round(sim.settings.home.lat * 1e7)


def test_mission_upload_refusals_name_the_problem():
    sim, gcs = connect()
    gcs.mav.mission_count_send(1, 1, 70000 % 65536 + 2000, 0)  # more than the vehicle holds
    run(sim, gcs, 0.1)
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_NO_SPACE
    bad_frame = gcs.mission_item(0, C.MAV_CMD_NAV_WAYPOINT, 47.4, 8.5, 10.0, frame=200)
    gcs.upload_mission([bad_frame])
    run(sim, gcs, 0.2)
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_UNSUPPORTED_FRAME
    bad_lat = gcs.mission_item(0, C.MAV_CMD_NAV_WAYPOINT, 95.0, 8.5, 10.0)
    gcs.upload_mission([bad_lat])
    run(sim, gcs, 0.2)
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_INVALID_PARAM5_X


def test_an_item_that_does_not_come_is_asked_for_again_then_given_up():
    sim, gcs = connect()
    gcs.mav.mission_count_send(1, 1, 3, 0)  # and then never send the items
    run(sim, gcs, 12)
    requests = [m.seq for m in gcs.of_type("MISSION_REQUEST_INT")]
    assert len(requests) >= 3 and set(requests) == {0}
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_OPERATION_CANCELLED


def test_clear_all_empties_the_plan():
    sim, gcs = connect("px4")
    gcs.upload_mission(square_mission(sim, gcs, home_first=False))
    run(sim, gcs, 2)
    gcs.mav.mission_clear_all_send(1, 1, C.MAV_MISSION_TYPE_ALL)
    run(sim, gcs, 0.1)
    gcs.download_mission()
    run(sim, gcs, 1)
    assert gcs.last["MISSION_COUNT"].count == 0


def test_ardupilot_flies_the_mission_in_auto_and_lands_where_it_says():
    sim, gcs = connect()
    gcs.set_interval(C.MAVLINK_MSG_ID_MISSION_CURRENT, 2)
    gcs.upload_mission(square_mission(sim, gcs, home_first=True))
    airborne(sim, gcs, 5.0)
    gcs.set_mode(ARDUPILOT_AUTO)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_MODE) == C.MAV_RESULT_ACCEPTED
    assert run(sim, gcs, 120, until=lambda: not sim.truth.armed)
    truth = sim.truth
    assert truth.landed and not truth.crashed
    assert math.hypot(truth.position[0] - 0.0, truth.position[1] - 30.0) < 1.0
    assert [m.seq for m in gcs.of_type("MISSION_ITEM_REACHED")] == [1, 2, 3, 5]
    assert {m.seq for m in gcs.of_type("MISSION_CURRENT")} >= {1, 2, 3, 5}


def test_ardupilot_refuses_auto_on_the_ground_without_a_takeoff_first():
    sim, gcs = connect()
    home = sim.settings.home
    gcs.upload_mission([
        gcs.mission_item(0, C.MAV_CMD_NAV_WAYPOINT, home.lat, home.lon, home.alt),
        gcs.mission_item(1, C.MAV_CMD_NAV_WAYPOINT, *latlon(sim, 10, 0), 10.0),
    ])
    settle(sim, gcs)
    gcs.set_mode(ARDUPILOT_GUIDED)
    gcs.arm()
    gcs.set_mode(ARDUPILOT_AUTO)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_MODE) == C.MAV_RESULT_FAILED
    assert "Auto: Missing Takeoff Cmd" in gcs.texts()


def test_px4_armed_in_mission_mode_takes_off_and_flies_it():
    sim, gcs = connect("px4")
    gcs.upload_mission(square_mission(sim, gcs, home_first=False))
    run(sim, gcs, 1)
    settle(sim, gcs)
    gcs.set_mode(PX4_MISSION, px4=True)
    gcs.arm()
    assert run(sim, gcs, 150, until=lambda: not sim.truth.armed)
    assert math.hypot(sim.truth.position[0], sim.truth.position[1] - 30.0) < 1.0
    assert [m.seq for m in gcs.of_type("MISSION_ITEM_REACHED")] == [0, 1, 2, 4]


def test_px4_takes_mission_mode_without_a_mission_and_stays_on_the_ground():
    # As PX4 SITL does: the mode is accepted; MISSION_CURRENT says there is no mission.
    sim, gcs = connect("px4")
    settle(sim, gcs)
    gcs.set_mode(PX4_MISSION, px4=True)
    gcs.arm()
    run(sim, gcs, 2)
    assert last_ack(gcs, C.MAV_CMD_DO_SET_MODE) == C.MAV_RESULT_ACCEPTED
    assert sim.truth.mode == "AUTO.MISSION" and sim.truth.landed
    current = gcs.last["MISSION_CURRENT"]
    assert current.mission_state == C.MISSION_STATE_NO_MISSION and current.mission_mode == 1


def test_mission_start_and_return_to_launch_item():
    sim, gcs = connect()
    home = sim.settings.home
    gcs.upload_mission([
        gcs.mission_item(0, C.MAV_CMD_NAV_WAYPOINT, home.lat, home.lon, home.alt),
        gcs.mission_item(1, C.MAV_CMD_NAV_TAKEOFF, alt=8.0),
        gcs.mission_item(2, C.MAV_CMD_NAV_LOITER_TIME, *latlon(sim, -15, 10), 8.0,
                         params=(3.0, 0, 0, 0)),
        gcs.mission_item(3, C.MAV_CMD_NAV_RETURN_TO_LAUNCH),
    ])
    airborne(sim, gcs, 3.0)
    gcs.command(C.MAV_CMD_MISSION_START, 2, 0)  # ArduPilot starts no mission part-way
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_MISSION_START) == C.MAV_RESULT_DENIED
    assert sim.truth.mode == "GUIDED"
    gcs.command(C.MAV_CMD_MISSION_START, 0, 0)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_MISSION_START) == C.MAV_RESULT_ACCEPTED
    assert sim.truth.mode == "AUTO"
    assert run(sim, gcs, 120, until=lambda: not sim.truth.armed)
    assert math.hypot(*sim.truth.position[:2]) < 1.0  # back home
    assert [m.seq for m in gcs.of_type("MISSION_ITEM_REACHED")] == [1, 2, 3]


# ----------------------------------------------------------------------------- targets
@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_global_position_target_is_reached(autopilot):
    sim, gcs = connect(autopilot)
    airborne(sim, gcs)
    lat, lon = latlon(sim, -25.0, 15.0)
    mask = 0b0000_1101_1111_1000  # position only

    def send():
        gcs.mav.set_position_target_global_int_send(
            0, 1, 1, C.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mask, int(lat * 1e7), int(lon * 1e7),
            14.0, 0, 0, 0, 0, 0, 0, 0, 0)

    if autopilot == "px4":  # OFFBOARD takes a stream of targets
        for _ in range(20):
            send()
            run(sim, gcs, 0.05)
        gcs.set_mode(PX4_OFFBOARD, px4=True)
    end = sim.time + 30
    while sim.time < end:
        send()
        run(sim, gcs, 0.1)
    x, y, z = sim.truth.position
    assert math.hypot(x + 25.0, y - 15.0) < 0.5 and z == pytest.approx(14.0, abs=0.3)


@pytest.mark.parametrize("autopilot, mode", [("ardupilot", "GUIDED"), ("px4", "AUTO.LOITER")])
def test_reposition_with_change_mode_flies_to_the_point(autopilot, mode):
    sim, gcs = connect(autopilot)
    airborne(sim, gcs)
    if autopilot == "ardupilot":
        gcs.set_mode(ARDUPILOT_LOITER)
    lat, lon = latlon(sim, 20.0, -10.0)
    amsl = sim.settings.home.alt + 15.0
    gcs.mav.command_int_send(1, 1, C.MAV_FRAME_GLOBAL_INT, C.MAV_CMD_DO_REPOSITION, 0, 0,
                             -1, C.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE, 0, NAN,
                             int(lat * 1e7), int(lon * 1e7), amsl)
    run(sim, gcs, 40)
    assert last_ack(gcs, C.MAV_CMD_DO_REPOSITION) == C.MAV_RESULT_ACCEPTED
    assert sim.truth.mode == mode
    x, y, z = sim.truth.position
    assert math.hypot(x - 20.0, y + 10.0) < 0.5 and z == pytest.approx(15.0, abs=0.3)


def test_ardupilot_reposition_outside_guided_without_the_flag_is_denied():
    sim, gcs = connect()
    airborne(sim, gcs)
    gcs.set_mode(ARDUPILOT_LOITER)
    lat, lon = latlon(sim, 20.0, 0.0)
    gcs.mav.command_int_send(1, 1, C.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                             C.MAV_CMD_DO_REPOSITION, 0, 0, -1, 0, 0, NAN,
                             int(lat * 1e7), int(lon * 1e7), 10.0)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_REPOSITION) == C.MAV_RESULT_DENIED


def test_ardupilot_guided_mission_item_flies_there_and_only_in_guided():
    sim, gcs = connect()
    airborne(sim, gcs)
    lat, lon = latlon(sim, 0.0, 25.0)
    item = gcs.mission_item(0, C.MAV_CMD_NAV_WAYPOINT, lat, lon, 12.0)
    item.current = 2
    gcs.mav.send(item)
    run(sim, gcs, 30)
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_ACCEPTED
    assert math.hypot(sim.truth.position[0], sim.truth.position[1] - 25.0) < 0.5
    gcs.set_mode(ARDUPILOT_LOITER)
    gcs.mav.send(item)
    run(sim, gcs, 0.2)
    assert gcs.last["MISSION_ACK"].type == C.MAV_MISSION_ERROR


def test_change_speed_limits_guided_flight():
    sim, gcs = connect()
    airborne(sim, gcs)
    gcs.command(C.MAV_CMD_DO_CHANGE_SPEED, 1, 3.0, -1, 0)
    gcs.goto_ned(0.0, 200.0, -10.0)
    run(sim, gcs, 20)
    assert last_ack(gcs, C.MAV_CMD_DO_CHANGE_SPEED) == C.MAV_RESULT_ACCEPTED
    assert math.hypot(*sim.truth.velocity[:2]) == pytest.approx(3.0, abs=0.2)


def test_ardupilot_change_speed_only_where_a_mode_has_a_speed():
    # GCS_MAVLINK_Copter::handle_MAV_CMD_DO_CHANGE_SPEED: LOITER has no speed to set
    # (FAILED, so MAVSDK's set_current_speed reports it); -1 is not a speed (DENIED).
    sim, gcs = connect()
    airborne(sim, gcs)
    gcs.command(C.MAV_CMD_DO_CHANGE_SPEED, 1, -1, -1, 0)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_CHANGE_SPEED) == C.MAV_RESULT_DENIED
    gcs.set_mode(ARDUPILOT_LOITER)
    gcs.command(C.MAV_CMD_DO_CHANGE_SPEED, 1, 3.0, -1, 0)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_CHANGE_SPEED) == C.MAV_RESULT_FAILED


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_hold_entered_at_speed_brakes_ahead_without_turning_back(autopilot):
    # ArduPilot's LOITER and PX4's Hold hold the stopping point, not where the mode began.
    sim, gcs = connect(autopilot)
    airborne(sim, gcs)
    if autopilot == "px4":
        gcs.goto_ned(0.0, 200.0, -10.0)
        gcs.set_mode(PX4_OFFBOARD, px4=True)
        for _ in range(300):  # a stream, as PX4 wants in OFFBOARD
            gcs.goto_ned(0.0, 200.0, -10.0)
            run(sim, gcs, 0.05)
    else:
        gcs.goto_ned(0.0, 200.0, -10.0)
        run(sim, gcs, 15)
    assert sim.truth.velocity[0] > 9.0  # east, at full speed
    gcs.set_mode(PX4_LOITER if autopilot == "px4" else ARDUPILOT_LOITER, px4=autopilot == "px4")
    east = []
    for _ in range(200):
        run(sim, gcs, 0.05)
        east.append(sim.truth.position[0])
    assert max(east) - east[-1] < 0.1  # no way back
    assert abs(sim.truth.velocity[0]) < 0.05


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_flight_termination_stops_the_motors_in_the_air(autopilot):
    sim, gcs = connect(autopilot)
    airborne(sim, gcs)
    gcs.command(C.MAV_CMD_DO_FLIGHTTERMINATION, 1)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_FLIGHTTERMINATION) == C.MAV_RESULT_ACCEPTED
    # ArduPilot Copter disarms; PX4 cuts the outputs and disarms once landed.
    assert sim.truth.armed == (autopilot == "px4")
    assert run(sim, gcs, 10, until=lambda: sim.truth.landed)
    run(sim, gcs, 3)
    assert not sim.truth.armed
    gcs.arm()
    run(sim, gcs, 0.2)
    if autopilot == "px4":  # until reboot
        assert last_ack(gcs, C.MAV_CMD_COMPONENT_ARM_DISARM) != C.MAV_RESULT_ACCEPTED


def test_ardupilot_flight_termination_needs_param1():
    sim, gcs = connect()
    settle(sim, gcs)
    gcs.command(C.MAV_CMD_DO_FLIGHTTERMINATION, 0)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_DO_FLIGHTTERMINATION) == C.MAV_RESULT_FAILED


def test_body_frame_velocity_moves_along_the_heading():
    sim, gcs = connect()
    airborne(sim, gcs)
    gcs.command(C.MAV_CMD_CONDITION_YAW, 90, 0, 1, 0)  # face east
    run(sim, gcs, 5)
    mask = 0b0000_1101_1100_0111  # velocity only
    for _ in range(40):
        gcs.mav.set_position_target_local_ned_send(0, 1, 1, C.MAV_FRAME_BODY_NED, mask,
                                                   0, 0, 0, 2.0, 0, 0, 0, 0, 0, 0, 0)
        run(sim, gcs, 0.1)
    vx, vy, _ = sim.truth.velocity  # ENU: forward is east
    assert vx == pytest.approx(2.0, abs=0.2) and abs(vy) < 0.2


# ----------------------------------------------------------------------------- signing
def test_setup_signing_refuses_unsigned_packets_and_obeys_signed_ones():
    sim, gcs = connect()
    settle(sim, gcs)
    key = bytes(range(32))
    gcs.mav.setup_signing_send(1, 1, key, 0)
    run(sim, gcs, 0.2)
    gcs.arm()  # unsigned: refused without an answer
    run(sim, gcs, 0.2)
    assert gcs.acks(C.MAV_CMD_COMPONENT_ARM_DISARM) == [] and not sim.truth.armed
    assert sim.server.links[0].refused_unsigned >= 1
    gcs.mav.signing.secret_key = key
    gcs.mav.signing.sign_outgoing = True
    gcs.mav.signing.timestamp = 4 * 10**13  # 2027: ahead of the vehicle's clock
    gcs.mav.signing.link_id = 1
    gcs.arm()
    run(sim, gcs, 0.2)
    # Our parser now holds the key and takes no unsigned packet: the ACK came signed.
    assert last_ack(gcs, C.MAV_CMD_COMPONENT_ARM_DISARM) == C.MAV_RESULT_ACCEPTED
    assert sim.truth.armed


def test_a_signing_key_from_boot_and_a_zero_key_turns_it_off():
    key = bytes(32 * [7])
    sim, gcs = connect(signing_key=key)
    run(sim, gcs, 1)
    assert gcs.counts["HEARTBEAT"] == 0  # our unsigned heartbeat was refused: silence
    gcs.mav.signing.secret_key = key
    gcs.mav.signing.sign_outgoing = True
    gcs.mav.signing.timestamp = 4 * 10**13  # 2027: ahead of the vehicle's clock
    gcs.heartbeat()
    run(sim, gcs, 1)
    assert gcs.counts["HEARTBEAT"] > 0
    gcs.mav.setup_signing_send(1, 1, bytes(32), 0)
    gcs.mav.signing.sign_outgoing = False
    gcs.mav.signing.secret_key = None
    run(sim, gcs, 0.1)
    gcs.command(C.MAV_CMD_REQUEST_MESSAGE, C.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
    run(sim, gcs, 0.2)
    assert last_ack(gcs, C.MAV_CMD_REQUEST_MESSAGE) == C.MAV_RESULT_ACCEPTED


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mission_current_at_the_end_is_the_last_item_and_complete(autopilot):
    # MAVSDK's is_mission_finished() trusts MISSION_CURRENT's state: the last item, COMPLETE.
    sim, gcs = connect(autopilot)
    items = square_mission(sim, gcs, home_first=autopilot == "ardupilot")
    gcs.upload_mission(items)
    run(sim, gcs, 2)
    if autopilot == "ardupilot":
        airborne(sim, gcs, 5.0)
        gcs.set_mode(ARDUPILOT_AUTO)
    else:
        settle(sim, gcs)
        gcs.set_mode(PX4_MISSION, px4=True)
        gcs.arm()
    assert run(sim, gcs, 150, until=lambda: not sim.truth.armed)
    unasked = gcs.of_type("MISSION_CURRENT")
    if autopilot == "ardupilot":
        assert unasked == []  # only in its stream, or when the current item is set
        gcs.set_interval(C.MAVLINK_MSG_ID_MISSION_CURRENT, 2)
        run(sim, gcs, 1)
    else:
        assert unasked  # on every change
    last = gcs.last["MISSION_CURRENT"]
    assert last.seq == len(items) - 1
    # total: ArduPilot leaves its home item out (seq == total on the last item); PX4 counts all.
    assert last.total == (len(items) - 1 if autopilot == "ardupilot" else len(items))
    assert last.mission_state == C.MISSION_STATE_COMPLETE


def test_ftp_requests_are_refused_at_once_so_ground_stations_fall_back():
    # MAVProxy asks for @PARAM/param.pck over MAVLink FTP first; without an answer it waits.
    sim, gcs = connect()
    open_ro = bytes([7, 0, 0, 4, 15, 0, 0, 0, 0, 0, 0, 0]) + b"@PARAM/param.pck\0"
    gcs.mav.file_transfer_protocol_send(0, 1, 1, list(open_ro.ljust(251, b"\0")))
    run(sim, gcs, 0.1)
    answer = bytes(gcs.last["FILE_TRANSFER_PROTOCOL"].payload)
    seq, opcode, size, req_opcode, error = answer[0], answer[3], answer[4], answer[5], answer[12]
    assert (seq, opcode, size, req_opcode) == (8, 129, 1, 4)  # NAK of OpenFileRO
    assert error == 7  # unknown command: this vehicle keeps no files
