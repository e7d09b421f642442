"""MAVSDK-Python (with the mavsdk_server its wheel ships) flies the vehicle, as a user would.

ArduPilot is reached over TCP (``tcpout://``); PX4 over UDP (``udpin://``), on the port it
sends to unasked. MAVSDK 3 requests no telemetry by itself, so the flight asks for the rates
it needs (ArduPilot Copter streams nothing unasked; PX4 streams anyway). ArduPilot keeps its
home at mission item 0, which MAVSDK's Mission plugin does not know about, so ArduPilot
missions go through MissionRaw with item 0 = home (as QGroundControl and MAVProxy send them);
PX4 missions go through the Mission plugin. Every await has a timeout.
"""

from __future__ import annotations

import asyncio
import math

import pytest
from conformance_support import HOME, arm_and_takeoff, connect, distance, offset, until, within
from mavsdk.mission import MissionItem, MissionPlan
from mavsdk.mission_raw import MissionItem as RawItem
from mavsdk.telemetry import LandedState, TelemetryError

pytestmark = pytest.mark.timeout(600)

AUTOPILOTS = ["ardupilot", "px4"]
# A float parameter each autopilot really has, and a value other than its default.
FLOAT_PARAM = {"ardupilot": ("WPNAV_SPEED", 750.0), "px4": ("MPC_XY_CRUISE", 6.5)}

MAV_FRAME_GLOBAL = 0
MAV_FRAME_GLOBAL_RELATIVE_ALT_INT = 6
MAV_CMD_NAV_WAYPOINT = 16
# *_INT frames mean the same as their float twins (ArduPilot answers with the latter).
SAME_FRAME = {5: 0, 6: 3, 11: 10}


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_mavsdk_reads_and_sets_a_parameter(start_vehicle, mavsdk_server, autopilot):
    """A parameter read, set and read back; the takeoff altitude; the attitude quaternion."""
    vehicle = start_vehicle(autopilot)
    name, new_value = FLOAT_PARAM[autopilot]

    async def scenario():
        drone = await connect(vehicle, mavsdk_server)
        old = await within(drone.param.get_param_float(name), vehicle.wall(20), f"get {name}")
        assert math.isfinite(old) and old > 0, f"{name} = {old}"
        assert old != new_value
        await within(
            drone.param.set_param_float(name, new_value), vehicle.wall(20), f"set {name}"
        )
        back = await within(drone.param.get_param_float(name), vehicle.wall(20), f"re-read {name}")
        assert back == pytest.approx(new_value, abs=1e-4), f"{name} read back as {back}"
        # PX4 keeps the takeoff altitude in MIS_TAKEOFF_ALT (a parameter set), ArduPilot in
        # MAVSDK itself: either way it must read back.
        await within(drone.action.set_takeoff_altitude(12.0), vehicle.wall(20), "takeoff alt")
        alt = await within(drone.action.get_takeoff_altitude(), vehicle.wall(20), "takeoff alt")
        assert alt == pytest.approx(12.0, abs=1e-4)

        # The attitude as a quaternion (ATTITUDE_QUATERNION): ArduPilot streams it when asked,
        # PX4 unasked (10 Hz on its normal links).
        tel = drone.telemetry
        if autopilot == "ardupilot":
            await within(tel.set_rate_attitude_quaternion(5.0), vehicle.wall(10), "q rate")
        q = await until(tel.attitude_quaternion(), lambda q: True, vehicle.wall(10), "quaternion")
        assert math.isclose(math.hypot(q.w, q.x, q.y, q.z), 1.0, abs_tol=1e-3), q
        # ALTITUDE: PX4 streams it unasked; ArduPilot has no such message and refuses its
        # rate, so MAVSDK says so instead of waiting forever.
        if autopilot == "px4":
            alt = await until(tel.altitude(), lambda a: True, vehicle.wall(10), "altitude")
            assert alt.altitude_amsl_m == pytest.approx(HOME[2], abs=1.0), alt
            assert abs(alt.altitude_relative_m) < 1.0, alt
        else:
            with pytest.raises(TelemetryError):
                await within(tel.set_rate_altitude(1.0), vehicle.wall(10), "altitude rate")

    asyncio.run(scenario())
    vehicle.alive()


def raw_mission(home: tuple[float, float, float], points) -> list[RawItem]:
    """ArduPilot's layout: item 0 is home (frame GLOBAL, AMSL), then the waypoints. Exactly
    one item is marked current (MAVSDK checks that): item 0, as QGroundControl marks it."""
    items = [
        RawItem(0, MAV_FRAME_GLOBAL, MAV_CMD_NAV_WAYPOINT, 1, 1, 0.0, 0.0, 0.0, 0.0,
                int(round(home[0] * 1e7)), int(round(home[1] * 1e7)), float(home[2]), 0)
    ]  # fmt: skip
    for lat, lon, alt in points:
        items.append(
            RawItem(len(items), MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, MAV_CMD_NAV_WAYPOINT, 0, 1,
                    0.0, 0.0, 0.0, 0.0, int(round(lat * 1e7)), int(round(lon * 1e7)), alt, 0)
        )  # fmt: skip
    return items


def plan_items(points) -> list[MissionItem]:
    nan = float("nan")
    return [
        MissionItem(lat, lon, alt, nan, False, nan, nan, MissionItem.CameraAction.NONE, nan, nan,
                    nan, nan, nan, MissionItem.VehicleAction.NONE)
        for lat, lon, alt in points
    ]  # fmt: skip


def assert_same_raw(uploaded: list[RawItem], downloaded: list[RawItem], home) -> None:
    assert len(downloaded) == len(uploaded), f"{len(downloaded)} items back, sent {len(uploaded)}"
    first = downloaded[0]
    assert first.command == MAV_CMD_NAV_WAYPOINT, first
    assert distance(first.x * 1e-7, first.y * 1e-7, home[0], home[1]) < 5.0, f"item 0 {first}"
    for sent, got in zip(uploaded[1:], downloaded[1:], strict=True):
        assert SAME_FRAME.get(got.frame, got.frame) == SAME_FRAME.get(sent.frame, sent.frame), (
            f"frame: sent {sent}, got {got}"
        )
        for key in ("seq", "command", "autocontinue", "x", "y", "mission_type"):
            assert getattr(got, key) == getattr(sent, key), f"{key}: sent {sent}, got {got}"
        for key in ("param1", "param2", "param3", "param4", "z"):
            assert getattr(got, key) == pytest.approx(getattr(sent, key), abs=0.01), (
                f"{key}: sent {sent}, got {got}"
            )


def assert_same_plan(uploaded: list[MissionItem], downloaded: list[MissionItem]) -> None:
    assert len(downloaded) == len(uploaded), f"{len(downloaded)} items back, sent {len(uploaded)}"
    for sent, got in zip(uploaded, downloaded, strict=True):
        assert got.latitude_deg == pytest.approx(sent.latitude_deg, abs=1.5e-7), got
        assert got.longitude_deg == pytest.approx(sent.longitude_deg, abs=1.5e-7), got
        assert got.relative_altitude_m == pytest.approx(sent.relative_altitude_m, abs=0.01), got
        assert got.is_fly_through == sent.is_fly_through, got


@pytest.mark.parametrize("autopilot", AUTOPILOTS)
def test_mavsdk_flies_goto_mission_and_return(start_vehicle, mavsdk_server, autopilot):
    """Arm, take off, go to a lat/lon, fly a 4-waypoint mission in AUTO (ArduPilot) or
    AUTO.MISSION (PX4), return to launch, see the vehicle land and disarm; download the
    mission and compare it with what was uploaded."""
    vehicle = start_vehicle(autopilot)
    w = vehicle.wall

    async def scenario():
        drone = await connect(vehicle, mavsdk_server)
        tel = drone.telemetry
        # ArduPilot Copter streams nothing until asked (its SRn_ rates default to 0) and
        # MAVSDK 3 asks for nothing by itself: a MAVSDK user sets the rates it needs.
        for rate, hz in (
            (tel.set_rate_position, 10.0),
            (tel.set_rate_health, 2.0),
            (tel.set_rate_landed_state, 2.0),
            (tel.set_rate_home, 1.0),
        ):
            await within(rate(hz), w(10), rate.__name__)

        await until(
            tel.health(),
            lambda h: h.is_global_position_ok and h.is_home_position_ok and h.is_armable,
            w(180),
            "health: global position, home and armable",
        )
        home = await until(tel.home(), lambda p: True, w(10), "home position")
        assert distance(home.latitude_deg, home.longitude_deg, HOME[0], HOME[1]) < 5.0, home
        h_lat, h_lon, h_amsl = home.latitude_deg, home.longitude_deg, home.absolute_altitude_m

        await within(drone.action.set_takeoff_altitude(10.0), w(20), "set takeoff altitude")
        await arm_and_takeoff(drone, vehicle)
        await until(tel.in_air(), lambda a: a, w(30), "in air")
        await until(
            tel.position(), lambda p: p.relative_altitude_m > 9.0, w(60), "climb to 10 m"
        )

        # A global target, altitude AMSL, yaw NaN (= keep the current heading).
        g_lat, g_lon = offset(h_lat, h_lon, 20.0, 15.0)
        await within(
            drone.action.goto_location(g_lat, g_lon, h_amsl + 15.0, float("nan")), w(20), "goto"
        )
        await until(
            tel.position(),
            lambda p: distance(p.latitude_deg, p.longitude_deg, g_lat, g_lon) < 2.0
            and abs(p.relative_altitude_m - 15.0) < 1.5,
            w(90),
            f"reach goto target {g_lat:.7f},{g_lon:.7f} at 15 m",
        )

        points = [
            (*offset(h_lat, h_lon, 40.0, 15.0), 15.0),
            (*offset(h_lat, h_lon, 40.0, -15.0), 20.0),
            (*offset(h_lat, h_lon, 10.0, -25.0), 15.0),
            (*offset(h_lat, h_lon, -10.0, -5.0), 12.0),
        ]
        if autopilot == "ardupilot":
            mission, uploaded = drone.mission_raw, raw_mission((h_lat, h_lon, h_amsl), points)
            await within(mission.upload_mission(uploaded), w(30), "upload mission (raw)")
        else:
            mission, uploaded = drone.mission, plan_items(points)
            await within(
                mission.upload_mission(MissionPlan(uploaded)), w(30), "upload mission"
            )

        closest = [math.inf] * len(points)
        progress: list[tuple[int, int]] = []

        async def watch_position():
            async for p in tel.position():
                for i, (lat, lon, _alt) in enumerate(points):
                    d = distance(p.latitude_deg, p.longitude_deg, lat, lon)
                    closest[i] = min(closest[i], d)

        async def watch_progress():
            async for pr in mission.mission_progress():
                progress.append((pr.current, pr.total))

        watchers = [asyncio.create_task(watch_position()), asyncio.create_task(watch_progress())]
        try:
            loop = asyncio.get_running_loop()
            if autopilot == "px4":
                # PX4 checks an uploaded mission before it lets MISSION run, and shows it in
                # MISSION_CURRENT (MAVSDK's mission progress) once checked. Asked sooner, it
                # refuses ("Switching to Mission is currently not available"), yet its first
                # COMMAND_ACK says ACCEPTED (a TEMPORARILY_REJECTED one follows), so
                # start_mission() returns as if it had worked. Wait for the mission to show.
                end = loop.time() + w(20)
                while not any(total == len(points) for _, total in progress):
                    assert loop.time() < end, f"uploaded mission not reported: {progress}"
                    await asyncio.sleep(vehicle.sim_sleep(0.2))
            # ... and ask again while the mode does not show (PX4 may still refuse it once).
            end = loop.time() + w(20)
            while True:
                await within(mission.start_mission(), w(20), "start mission")
                try:
                    await until(
                        tel.flight_mode(),
                        lambda m: m.name == "MISSION",
                        1.0 + vehicle.sim_sleep(3.0),
                        "flight mode MISSION (AUTO / AUTO.MISSION)",
                    )
                    break
                except AssertionError:
                    if loop.time() > end:
                        raise
            end = asyncio.get_running_loop().time() + w(200)
            while not await within(mission.is_mission_finished(), w(10), "mission finished?"):
                if asyncio.get_running_loop().time() > end:
                    raise AssertionError(
                        f"mission not finished in {w(200):.0f} s; progress {progress}, "
                        f"closest approach per waypoint {closest} m"
                    )
                await asyncio.sleep(vehicle.sim_sleep(1.0))
            await until(
                tel.position(),
                lambda p: distance(p.latitude_deg, p.longitude_deg, *points[-1][:2]) < 3.0,
                w(30),
                "at the last waypoint",
            )
        finally:
            for task in watchers:
                task.cancel()
            await asyncio.gather(*watchers, return_exceptions=True)
        assert all(d < 5.0 for d in closest), f"closest approach per waypoint {closest} m"
        assert progress, "no mission progress reported"

        await within(drone.action.return_to_launch(), w(20), "return to launch")
        await until(tel.flight_mode(), lambda m: m.name == "RETURN_TO_LAUNCH", w(20), "RTL mode")
        await until(tel.armed(), lambda a: not a, w(240), "land at home and disarm")
        await until(
            tel.landed_state(), lambda s: s == LandedState.ON_GROUND, w(20), "landed state"
        )
        p = await until(tel.position(), lambda p: True, w(10), "position")
        assert distance(p.latitude_deg, p.longitude_deg, h_lat, h_lon) < 3.0, p
        assert abs(p.relative_altitude_m) < 1.0, p

        if autopilot == "ardupilot":
            downloaded = await within(mission.download_mission(), w(30), "download mission")
            assert_same_raw(uploaded, downloaded, (h_lat, h_lon))
        else:
            plan = await within(mission.download_mission(), w(30), "download mission")
            assert_same_plan(uploaded, plan.mission_items)

    asyncio.run(scenario())
    vehicle.alive()
