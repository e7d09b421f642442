"""MAVSDK-Python's common copter calls beyond the basic flight, one scenario per autopilot:
vehicle information, telemetry values, the return altitude, a geofence, offboard control,
hold, the speed setting, a mission paused, resumed and skipped ahead that returns home, and
the emergency stops (kill, terminate). On PX4 the offboard setpoints also stop for a while
(mavsdk_server paused), and PX4 fails safe into Hold.

What MAVSDK 3.10 sends (its C++ sources, tag v3.10.2): offboard.start() asks for GUIDED on
ArduPilot and OFFBOARD on PX4 and stop() for Hold (LOITER, AUTO.LOITER); hold() and
pause_mission() ask for Hold too; goto_location() first switches to GUIDED (ArduPilot) or Hold
(PX4); set_current_speed() is MAV_CMD_DO_CHANGE_SPEED (ground speed); the return altitude is
the parameter RTL_RETURN_ALT on any autopilot, which ArduPilot has not (its RTL_ALT is in
cm), so MAVSDK reports a parameter error there; kill() is a forced disarm, terminate()
MAV_CMD_DO_FLIGHTTERMINATION. MAVSDK streams offboard setpoints at 20 Hz of wall time, so the
embedded SITL runs these scenarios at a lower speed-up than the others.
"""

from __future__ import annotations

import asyncio
import math
import os
import signal

import pytest
from conformance_support import (
    HOME,
    Monitor,
    arm_and_takeoff,
    collect_status_texts,
    connect,
    distance,
    mode,
    offset,
    until,
    within,
)
from mavsdk.action import ActionError
from mavsdk.geofence import FenceType, GeofenceData, Point, Polygon
from mavsdk.info import Version
from mavsdk.mission import MissionItem, MissionPlan
from mavsdk.mission_raw import MissionItem as RawItem
from mavsdk.offboard import PositionNedYaw, VelocityBodyYawspeed, VelocityNedYaw
from mavsdk.telemetry import FixType

from sitl.copter.telemetry import build_hash, custom_versions

pytestmark = pytest.mark.timeout(600)

# Offboard setpoints arrive at 20 Hz of wall time: at 5x that is 4 per simulated second,
# twice what PX4 needs to stay in OFFBOARD.
SPEEDUP = 5.0
CRUISE = 12.0  # m above home: the offboard, goto and mission legs
RTL_ALTITUDE = 20.0  # m above home the return climbs to
SLOW = 3.0  # m/s set with set_current_speed

MAV_FRAME_GLOBAL = 0
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
MAV_CMD_NAV_WAYPOINT = 16
MAV_CMD_NAV_RETURN_TO_LAUNCH = 20
MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION = 5001
MAV_MISSION_TYPE_FENCE = 1
PX4_HOLD = (4 << 16) | (3 << 24)  # AUTO.LOITER in PX4's HEARTBEAT custom_mode


def raw_item(seq: int, frame: int, command: int, lat=0.0, lon=0.0, alt=0.0, current=0):
    return RawItem(seq, frame, command, current, 1, 0.0, 0.0, 0.0, 0.0,
                   int(round(lat * 1e7)), int(round(lon * 1e7)), float(alt), 0)  # fmt: skip


def plan_item(lat: float, lon: float, alt: float) -> MissionItem:
    nan = float("nan")
    return MissionItem(lat, lon, alt, nan, False, nan, nan, MissionItem.CameraAction.NONE,
                       nan, nan, nan, nan, nan, MissionItem.VehicleAction.NONE)  # fmt: skip


def speed(v) -> float:
    return math.hypot(v.north_m_s, v.east_m_s)


async def offboard_loss(vehicle, server) -> None:
    """Pause ``server`` (a mavsdk_server streaming offboard setpoints) until the PX4 on
    ``vehicle`` leaves OFFBOARD for Hold, seen on its ground-station port."""
    monitor = Monitor(f"udpin:127.0.0.1:{vehicle.gcs_port}")
    os.kill(server.pid, signal.SIGSTOP)
    try:
        await asyncio.to_thread(
            monitor.wait,
            lambda m: m.custom_mode() == PX4_HOLD,
            vehicle.wall(10),
            "Hold after the offboard setpoints stopped",
        )
    finally:
        os.kill(server.pid, signal.SIGCONT)
        monitor.close()


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mavsdk_common_calls(start_vehicle, mavsdk_server, autopilot):
    vehicle = start_vehicle(autopilot, speedup=SPEEDUP)
    w = vehicle.wall
    ardupilot = autopilot == "ardupilot"

    async def scenario():
        drone = await connect(vehicle, mavsdk_server)
        tel, action = drone.telemetry, drone.action
        collector, texts = collect_status_texts(tel)
        if ardupilot:  # ArduPilot streams nothing until asked
            for rate, hz in (
                (tel.set_rate_position, 10.0),
                (tel.set_rate_velocity_ned, 10.0),
                (tel.set_rate_position_velocity_ned, 10.0),
                (tel.set_rate_health, 2.0),
                (tel.set_rate_landed_state, 2.0),
                (tel.set_rate_home, 1.0),
                (tel.set_rate_battery, 2.0),
                (tel.set_rate_gps_info, 2.0),
                (tel.set_rate_attitude_euler, 10.0),
            ):
                await within(rate(hz), w(10), rate.__name__)

        # --- AUTOPILOT_VERSION as MAVSDK's Info reads it.
        version = await within(drone.info.get_version(), w(10), "version")
        major = {"ardupilot": 4, "px4": 1}[autopilot]
        assert version.flight_sw_major == major, version
        assert version.flight_sw_version_type == Version.FlightSoftwareVersionType.RELEASE
        product = await within(drone.info.get_product(), w(10), "product")
        assert product.vendor_id >= 0 and product.product_id >= 0, product
        ident = await within(drone.info.get_identification(), w(10), "identification")
        assert isinstance(ident.hardware_uid, str), ident
        # MAVSDK shows flight_custom_version's bytes reversed as hex (its first 9 digits, in
        # 3.10): PX4's git hash, ArduPilot's hash text backwards. ArduPilot reports no uid.
        shown = version.flight_sw_git_hash.rstrip("\x00")
        assert len(shown) >= 8 and all(c in "0123456789abcdef" for c in shown), version
        if ardupilot:
            assert ident.legacy_uid == 0, ident
        if not vehicle.real:  # this checkout's hash, each autopilot's way
            flight, _ = custom_versions(autopilot, build_hash())
            assert bytes(reversed(flight)).hex().startswith(shown), version
            assert ardupilot or build_hash().startswith(shown), version
            vendor = (version.flight_sw_vendor_major, version.flight_sw_vendor_minor,
                      version.flight_sw_vendor_patch)
            assert ardupilot or vendor == (0, 0, 0), version

        # --- Telemetry that users read first, with sane values.
        await until(tel.health(), lambda h: h.is_global_position_ok, w(60), "position ok")
        battery = await until(tel.battery(), lambda b: True, w(10), "battery")
        assert 10.0 < battery.voltage_v < 60.0 and 0.0 < battery.remaining_percent <= 100.0, (
            battery
        )
        gps = await until(tel.gps_info(), lambda g: g.fix_type == FixType.FIX_3D, w(30), "gps")
        assert gps.num_satellites >= 6, gps
        att = await until(tel.attitude_euler(), lambda a: True, w(10), "attitude")
        assert abs(att.roll_deg) < 5.0 and abs(att.pitch_deg) < 5.0, att
        assert -180.0 <= att.yaw_deg <= 360.0, att
        v = await until(tel.velocity_ned(), lambda v: True, w(10), "velocity")
        assert speed(v) < 0.1 and abs(v.down_m_s) < 0.1, v

        # --- The return altitude: PX4's RTL_RETURN_ALT through MAVSDK; ArduPilot has no such
        # parameter and ignores it (MAVSDK times out), its RTL_ALT is in cm.
        if ardupilot:
            with pytest.raises(ActionError):
                await within(action.set_return_to_launch_altitude(RTL_ALTITUDE), w(20), "rtl alt")
            await within(
                drone.param.set_param_int("RTL_ALT", int(RTL_ALTITUDE * 100)), w(20), "RTL_ALT"
            )
            back = await within(drone.param.get_param_int("RTL_ALT"), w(20), "RTL_ALT")
            assert back == int(RTL_ALTITUDE * 100)
        else:
            await within(action.set_return_to_launch_altitude(RTL_ALTITUDE), w(20), "rtl alt")
            back = await within(action.get_return_to_launch_altitude(), w(20), "rtl alt")
            assert back == pytest.approx(RTL_ALTITUDE)

        # --- A geofence (MISSION_ITEM_INT, mission type FENCE): uploaded, read back, cleared.
        corners = [offset(HOME[0], HOME[1], n, e) for n, e in
                   ((-200, -200), (-200, 200), (200, 200), (200, -200))]  # fmt: skip
        fence = GeofenceData(
            [Polygon([Point(lat, lon) for lat, lon in corners], FenceType.INCLUSION)], []
        )
        await within(drone.geofence.upload_geofence(fence), w(20), "upload geofence")
        items = await within(drone.mission_raw.download_geofence(), w(20), "download geofence")
        assert [i.command for i in items] == [MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION] * 4
        assert all(i.param1 == 4 and i.mission_type == MAV_MISSION_TYPE_FENCE for i in items)
        got = [(i.x * 1e-7, i.y * 1e-7) for i in items]
        assert all(distance(*a, *b) < 0.1 for a, b in zip(got, corners, strict=True)), got
        await within(drone.geofence.clear_geofence(), w(20), "clear geofence")
        items = await within(drone.mission_raw.download_geofence(), w(20), "download geofence")
        assert items == []

        # --- Take off, then offboard: position, then velocity in body axes, then stop (Hold).
        await within(action.set_takeoff_altitude(CRUISE), w(20), "takeoff altitude")
        await arm_and_takeoff(drone, vehicle)
        await until(tel.position(), lambda p: p.relative_altitude_m > CRUISE - 1.0, w(60),
                    "climb")  # fmt: skip
        offboard = drone.offboard
        if not ardupilot:  # room for a stall of MAVSDK's wall-clock stream on a busy machine
            await within(drone.param.set_param_float("COM_OF_LOSS_T", 3.0), w(10), "loss time")
        # A setpoint first (MAVSDK then streams it), then the mode, as MAVSDK's examples do.
        await within(offboard.set_velocity_ned(VelocityNedYaw(0, 0, 0, 0)), w(10), "setpoint")
        loop = asyncio.get_running_loop()
        end = loop.time() + w(10)
        while True:
            await within(offboard.start(), w(10), "offboard start")
            try:
                await mode(tel, "OFFBOARD", 1.0 + vehicle.sim_sleep(2.0))
                break
            except AssertionError:
                if loop.time() > end:
                    raise
        target = (15.0, 5.0, -CRUISE)
        await within(offboard.set_position_ned(PositionNedYaw(*target, 0.0)), w(10), "pos")
        await until(
            tel.position_velocity_ned(),
            lambda pv: math.dist((pv.position.north_m, pv.position.east_m, pv.position.down_m),
                                 target) < 0.5 and speed(pv.velocity) < 0.3,
            w(30),
            f"offboard position {target}",
        )  # fmt: skip
        if not ardupilot:
            # The setpoints stop (mavsdk_server paused): after COM_OF_LOSS_T PX4 fails safe
            # into Hold, as a listening ground station sees; MAVSDK, resumed, sees it too.
            await offboard_loss(vehicle, mavsdk_server.processes[-1])
            await mode(tel, "HOLD", w(10))
            await within(offboard.set_velocity_ned(VelocityNedYaw(0, 0, 0, 0)), w(10), "again")
            await within(offboard.start(), w(10), "offboard start again")
            await mode(tel, "OFFBOARD", w(10))
        await within(
            offboard.set_velocity_body(VelocityBodyYawspeed(2.0, 0.0, 0.0, 0.0)), w(10), "vel"
        )
        v = await until(tel.velocity_ned(), lambda v: speed(v) > 1.9, w(20), "body velocity")
        assert v.north_m_s > 1.8 and abs(v.east_m_s) < 0.3, v  # heading north: forward = north
        await within(offboard.stop(), w(10), "offboard stop")
        await mode(tel, "HOLD", w(10))
        await until(tel.velocity_ned(), lambda v: speed(v) < 0.2, w(20), "stopped in Hold")

        # --- The speed setting. ArduPilot's LOITER refuses it (no speed to set there);
        # GUIDED and PX4's Hold take it, and the vehicle then flies at that speed.
        if ardupilot:
            with pytest.raises(ActionError):
                await within(action.set_current_speed(SLOW), w(10), "speed in LOITER")
        here = await until(tel.position(), lambda p: True, w(10), "position")
        g_lat, g_lon = offset(HOME[0], HOME[1], 15.0, 35.0)
        await within(
            action.goto_location(g_lat, g_lon, here.absolute_altitude_m, float("nan")), w(10),
            "goto",
        )  # fmt: skip
        await within(action.set_current_speed(SLOW), w(10), "set speed")
        fastest = 0.0

        async def watch_speed():
            nonlocal fastest
            async for v in tel.velocity_ned():
                fastest = max(fastest, speed(v))

        watcher = asyncio.create_task(watch_speed())
        try:
            await until(
                tel.position(),
                lambda p: distance(p.latitude_deg, p.longitude_deg, g_lat, g_lon) < 1.0,
                w(40),
                "goto target",
            )
        finally:
            watcher.cancel()
        assert SLOW * 0.85 < fastest < SLOW * 1.1, f"flew at up to {fastest:.2f} m/s"
        await within(action.hold(), w(10), "hold")
        await mode(tel, "HOLD", w(10))

        # --- A mission: paused on the way to its second waypoint, resumed, skipped ahead to
        # its last, then the return: ArduPilot's RTL item; PX4's by MAVSDK's
        # set_return_to_launch_after_mission (an RTL item appended).
        points = [
            (*offset(HOME[0], HOME[1], 30.0, 35.0), CRUISE),
            (*offset(HOME[0], HOME[1], 30.0, -5.0), CRUISE),
            (*offset(HOME[0], HOME[1], 5.0, -5.0), CRUISE),
        ]
        if ardupilot:
            mission = drone.mission_raw
            items = [raw_item(0, MAV_FRAME_GLOBAL, MAV_CMD_NAV_WAYPOINT, *HOME, current=1)]
            for lat, lon, alt in points:
                items.append(raw_item(len(items), MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                      MAV_CMD_NAV_WAYPOINT, lat, lon, alt))  # fmt: skip
            items.append(raw_item(len(items), MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
                                  MAV_CMD_NAV_RETURN_TO_LAUNCH))  # fmt: skip
            await within(mission.upload_mission(items), w(30), "upload mission")
            last = 3  # sequence number (item 0 is home)
        else:
            mission = drone.mission
            await within(mission.set_return_to_launch_after_mission(True), w(10), "rtl after")
            plan = MissionPlan([plan_item(*p) for p in points])
            await within(mission.upload_mission(plan), w(30), "upload mission")
            last = 2  # mission item index
        progress: list[tuple[int, int]] = []

        async def watch_progress():
            async for pr in mission.mission_progress():
                progress.append((pr.current, pr.total))

        progress_watcher = asyncio.create_task(watch_progress())
        if not ardupilot:  # PX4 reports the mission once it has checked it
            end = loop.time() + w(20)
            while not any(total >= len(points) for _, total in progress):
                assert loop.time() < end, f"uploaded mission not reported: {progress}"
                await asyncio.sleep(vehicle.sim_sleep(0.2))
        end = loop.time() + w(20)
        while True:
            await within(mission.start_mission(), w(10), "start mission")
            try:
                await mode(tel, "MISSION", 1.0 + vehicle.sim_sleep(3.0))
                break
            except AssertionError:
                if loop.time() > end:
                    raise
        await until(
            tel.position(),
            lambda p: distance(p.latitude_deg, p.longitude_deg, *points[0][:2]) < 3.0,
            w(60),
            "at waypoint 1",
        )
        await until(
            tel.position(),
            lambda p: distance(p.latitude_deg, p.longitude_deg, *points[0][:2]) > 6.0,
            w(30),
            "on the way to waypoint 2",
        )
        await within(mission.pause_mission(), w(10), "pause mission")
        await mode(tel, "HOLD", w(10))
        # Both autopilots brake to a stop ahead, and stay there.
        paused = await until(tel.velocity_ned(), lambda v: speed(v) < 0.2, w(20), "paused")
        held = await until(tel.position(), lambda p: True, w(10), "position")
        await asyncio.sleep(vehicle.sim_sleep(2.0))
        still = await until(tel.position(), lambda p: True, w(10), "position")
        moved = distance(held.latitude_deg, held.longitude_deg, still.latitude_deg,
                         still.longitude_deg)  # fmt: skip
        assert moved < 0.5, f"moved {moved:.2f} m while paused ({paused})"
        far = distance(still.latitude_deg, still.longitude_deg, *points[1][:2])
        assert far > 5.0, "paused too late to tell a resume from a restart"
        await within(mission.start_mission(), w(10), "resume mission")
        await mode(tel, "MISSION", w(10))
        await until(
            tel.position(),
            lambda p: distance(p.latitude_deg, p.longitude_deg, *points[1][:2]) < 3.0,
            w(60),
            "resumed to waypoint 2",
        )
        await within(mission.set_current_mission_item(last), w(10), "set current item")
        await until(
            tel.position(),
            lambda p: distance(p.latitude_deg, p.longitude_deg, *points[2][:2]) < 3.0,
            w(60),
            "at the last waypoint",
        )
        # The return climbs to the return altitude before it heads home.
        top = await until(
            tel.position(),
            lambda p: p.relative_altitude_m > RTL_ALTITUDE - 0.5,
            w(60),
            f"return climbs to {RTL_ALTITUDE} m",
        )
        assert distance(top.latitude_deg, top.longitude_deg, *points[2][:2]) < 3.0, top

        progress_watcher.cancel()
        assert any(current == last for current, _ in progress), progress

        # --- Emergency stops, high up: both autopilots stop the motors at once.
        first, second_stop = (action.terminate, action.kill) if ardupilot else (
            action.kill, action.terminate)  # fmt: skip
        await within(first(), w(10), first.__name__)
        await until(tel.armed(), lambda a: not a, w(10), "motors stopped")
        await until(tel.position(), lambda p: p.relative_altitude_m < 1.0, w(30), "fell")
        await within(second_stop(), w(10), second_stop.__name__)
        if not ardupilot:  # PX4 keeps a flight termination until reboot
            with pytest.raises(ActionError):
                await within(action.arm(), w(10), "arm after termination")

        # --- Clearing the mission: ArduPilot keeps its home item. (Read raw: MAVSDK's Mission
        # plugin makes one empty item of an empty list.)
        await within(mission.clear_mission(), w(20), "clear mission")
        left = await within(drone.mission_raw.download_mission(), w(20), "download mission")
        assert len(left) == (1 if ardupilot else 0), [str(i) for i in left]

        collector.cancel()
        expected = "Arming motors" if ardupilot else "Armed by external command"
        assert expected in texts, texts

    asyncio.run(scenario())
    vehicle.alive()
