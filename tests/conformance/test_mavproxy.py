"""MAVProxy (the ArduPilot ground station) on the vehicle, driven through its console.

Commands are typed on MAVProxy's stdin; its output is the evidence for what it was told
(parameter values, COMMAND_ACK / MISSION_ACK, mode and arming announcements, alarms). Where a
position matters, a pymavlink listener reads the telemetry MAVProxy forwards (``--out``). Its
state (logs, parameter and waypoint files) goes to a temporary folder.

ArduPilot is flown end to end (GUIDED takeoff, two lat/lon targets, a mission in AUTO ending
in a landing). MAVProxy does not fly PX4 (its takeoff, guided and waypoint commands follow
ArduPilot's conventions), so against PX4 it connects, fetches, shows and sets parameters and
must announce nothing false but the one thing it says of every PX4 (see PX4_FENCE below).
"""

from __future__ import annotations

import re
import time

import pytest
from conformance_support import HOME, Monitor, distance, free_port, mavproxy_master, offset
from pymavlink import mavutil

pytestmark = pytest.mark.timeout(600)

FLOAT_PARAM = {"ardupilot": ("WPNAV_SPEED", 750.0), "px4": ("MPC_XY_CRUISE", 6.5)}
# What MAVProxy says when the vehicle reports a problem; a healthy vehicle on the ground
# (and in a normal flight) makes it say none of these.
ALARMS = re.compile(
    r"fence breach|GPS fix lost|Flight battery warning|Cell warning|Calibration failed"
    r"|link \d+ down|no link",
    re.IGNORECASE,
)
# MAVProxy's fence module says "fence breach" whenever SYS_STATUS does not report the geofence
# healthy. PX4 reports no geofence in SYS_STATUS at all (its present, enabled and health bits
# clear), so MAVProxy says it on connecting to real PX4 SITL: against PX4 the evidence is
# instead that no SYS_STATUS claims an enabled (or present) geofence.
PX4_FENCE = re.compile(r"(?:^|>\s*)fence breach$", re.IGNORECASE)  # after a prompt, if any
# Real PX4 SITL streams seven messages at 50 Hz of its own time on its ground-station link; at
# PX4_SIM_SPEED_FACTOR 5 MAVProxy cannot read that fast, the kernel drops its datagrams and
# the parameter download stalls (515 of 917 after 50 s): real PX4 meets MAVProxy at 1x. The
# embedded SITL keeps CONFORMANCE_SPEEDUP.
PX4_MAVPROXY_SPEEDUP = 1.0
COPTER_MODE = {"AUTO": 3, "GUIDED": 4, "RTL": 6, "LAND": 9}
MAV_CMD_NAV_WAYPOINT, MAV_CMD_NAV_LAND = 16, 21
# *_INT frames mean the same as their float twins (ArduPilot answers with the latter).
SAME_FRAME = {5: 0, 6: 3, 11: 10}
# `param show NAME` prints the name and its value (after MAVProxy's prompt, if any).
NUMBER = r"\b{}\s+(-?\d[\d.eE+-]*)"


def alarms(lines: list[str], autopilot: str = "ardupilot") -> list[str]:
    said = [line for line in lines if ALARMS.search(line)]
    if autopilot == "px4":
        said = [line for line in said if not PX4_FENCE.search(line.strip())]
    return said


def check_parameters(mp, vehicle, autopilot: str) -> None:
    name, value = FLOAT_PARAM[autopilot]
    mp.expect(r"Received \d+ parameters", vehicle.wall(120), "parameter download")
    mp.mark()
    mp.send(f"param show {name}")
    old = float(mp.expect(NUMBER.format(name), vehicle.wall(5), f"param show {name}").group(1))
    assert old > 0 and old != value, f"{name} = {old}"
    mp.send(f"param set {name} {value:g}")
    # MAVProxy sets in the background (retrying) and says only "Failed to set" on failure;
    # its parameter cache takes the vehicle's PARAM_VALUE answer.
    end = time.monotonic() + vehicle.wall(20)
    while True:
        mp.mark()
        mp.send(f"param show {name}")
        shown = float(mp.expect(NUMBER.format(name), vehicle.wall(5), f"param show {name}")[1])
        if shown == pytest.approx(value, abs=1e-4):
            break
        failed = [line for line in mp.output() if "Failed to set" in line]
        assert not failed and time.monotonic() < end, f"param set {name}: {failed or shown}"
        time.sleep(vehicle.sim_sleep(0.5))
    mp.mark()
    mp.send(f"param fetch {name}")
    fetched = mp.expect(rf"\b{name} = (-?\d[\d.eE+-]*)", vehicle.wall(20), f"param fetch {name}")
    assert float(fetched.group(1)) == pytest.approx(value, abs=1e-4), fetched.group(0)


def relayed(mavproxy, vehicle, keep=()):
    """MAVProxy on ``vehicle``, and a pymavlink Monitor of what MAVProxy relays to its
    --out port: (the MAVProxy process, the Monitor)."""
    out = free_port()
    mp = mavproxy(mavproxy_master(vehicle), "--out", f"udp:127.0.0.1:{out}")
    return mp, Monitor(f"udpin:127.0.0.1:{out}", keep=keep)


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mavproxy_parameters_and_no_false_alarms(start_vehicle, mavproxy, autopilot):
    vehicle = start_vehicle(autopilot, px4_speedup=PX4_MAVPROXY_SPEEDUP)
    mp, monitor = relayed(mavproxy, vehicle, keep=("SYS_STATUS",))
    try:
        check_parameters(mp, vehicle, autopilot)
        # MAVProxy asks ArduPilot for every data stream (PX4 streams anyway), its HUD (and
        # QGroundControl's) included: VFR_HUD, the EXTRA2 group.
        monitor.wait(lambda m: m.get("VFR_HUD"), vehicle.wall(10), "VFR_HUD")
        # Give the ground station 20 s of the vehicle's own time on the ground to complain.
        start = monitor.wait(lambda m: m.boot_seconds(), vehicle.wall(10), "vehicle time")
        monitor.wait(
            lambda m: m.boot_seconds() > start + 20 and m.counts.get("SYS_STATUS", 0) >= 5,
            vehicle.wall(20),
            "20 s of the vehicle's time with SYS_STATUS",
        )
    finally:
        monitor.close()
    said = alarms(mp.output(), autopilot)
    assert not said, f"MAVProxy announced: {said}"
    if autopilot == "px4":
        fence = mavutil.mavlink.MAV_SYS_STATUS_GEOFENCE
        claimed = [
            s for s in monitor.kept["SYS_STATUS"]
            if (s.onboard_control_sensors_present | s.onboard_control_sensors_enabled) & fence
        ]  # fmt: skip
        assert not claimed, f"a geofence reported present or enabled: {claimed[:1]}"
    vehicle.alive()


def test_mavproxy_sets_home_on_ardupilot(start_vehicle, mavproxy):
    """`command_int GLOBAL_RELATIVE_ALT DO_SET_HOME ...` (MAVProxy's own example of the
    command) moves home 30 m east: ACCEPTED, and HOME_POSITION follows at once."""
    vehicle = start_vehicle("ardupilot")
    w = vehicle.wall
    mp, monitor = relayed(mavproxy, vehicle)
    try:
        home_msg = monitor.wait(lambda m: m.get("HOME_POSITION"), w(180), "HOME_POSITION")
        home = (home_msg.latitude * 1e-7, home_msg.longitude * 1e-7)
        lat, lon = offset(home[0], home[1], 0.0, 30.0)
        mp.mark()
        mp.send(f"command_int GLOBAL_RELATIVE_ALT DO_SET_HOME 0 0 0 0 0 0 "
                f"{round(lat * 1e7)} {round(lon * 1e7)} 0")
        mp.expect(r"COMMAND_ACK: DO_SET_HOME: ACCEPTED", w(10), "DO_SET_HOME accepted")
        monitor.wait(
            lambda m: distance(m.get("HOME_POSITION").latitude * 1e-7,
                               m.get("HOME_POSITION").longitude * 1e-7, lat, lon) < 0.5,
            w(10),
            "HOME_POSITION at the new home",
        )
        moved = monitor.get("HOME_POSITION")
        assert abs(moved.altitude - home_msg.altitude) < 100, (home_msg, moved)  # mm
    finally:
        monitor.close()
    said = mp.output()
    assert not alarms(said), f"MAVProxy announced: {alarms(said)}"
    vehicle.alive()


def arming_parameters(mp, timeout: float) -> dict[str, float]:
    """The vehicle's ARMING_* parameters as MAVProxy holds them."""
    start = mp.mark()
    mp.send("param show ARMING_*")
    mp.send("param show WPNAV_SPEED")  # printed after every ARMING_* line
    mp.expect(NUMBER.format("WPNAV_SPEED"), timeout, "param show")
    found = (re.search(NUMBER.format(r"(ARMING_\w+)"), line) for line in mp.output(start))
    return {m[1]: float(m[2]) for m in found if m}


def write_wpl(path, home, items) -> None:
    """A QGC WPL 110 file: item 0 home (AMSL), then (command, lat, lon, alt above home, p4)."""
    lat, lon, alt = home
    lines = ["QGC WPL 110", f"0\t1\t0\t16\t0\t0\t0\t0\t{lat:.7f}\t{lon:.7f}\t{alt:.6f}\t1"]
    for seq, (command, lat, lon, alt, p4) in enumerate(items, start=1):
        lines.append(
            f"{seq}\t0\t3\t{command}\t0\t0\t0\t{p4:g}\t{lat:.7f}\t{lon:.7f}\t{alt:.6f}\t1"
        )
    path.write_text("\n".join(lines) + "\n")


LISTED = re.compile(
    r"(\d+) (\d+) (-?\d+\.\d+) (-?\d+\.\d+) (-?\d+\.\d+) "
    r"p1=(\S+) p2=(\S+) p3=(\S+) p4=(\S+) cur=(\d+) auto=(\d+)$"
)


def parse_listed(m: re.Match) -> dict:
    """One item as `wp list` prints it: command frame lat lon alt p1..p4 current auto."""
    return {
        "command": int(m[1]), "frame": int(m[2]), "x": float(m[3]), "y": float(m[4]),
        "z": float(m[5]), "params": [float(m[i]) for i in range(6, 10)],
        "autocontinue": int(m[11]),
    }  # fmt: skip


def test_mavproxy_flies_guided_and_a_mission_on_ardupilot(start_vehicle, mavproxy, tmp_path):
    """mode guided, arm throttle, takeoff 10, guided LAT LON ALT (MAV_CMD_DO_REPOSITION, then
    a guided MISSION_ITEM_INT with current=2), wp load, mode auto through 3 waypoints and a
    landing, see the vehicle disarm; wp list returns what was loaded."""
    vehicle = start_vehicle("ardupilot")
    w = vehicle.wall
    mp, monitor = relayed(mavproxy, vehicle)
    try:
        mp.expect(r"Received \d+ parameters", w(120), "parameter download")
        arming = arming_parameters(mp, w(10))
        # ArduPilot up to 4.6 has ARMING_CHECK (1 = all checks), 4.7 ARMING_SKIPCHK (0 = skip
        # none); MAVProxy 1.8.74 reads only the first, and without it says "Arming checks
        # disabled" whatever the vehicle does.
        assert arming.get("ARMING_CHECK") == 1 or arming.get("ARMING_SKIPCHK") == 0, arming
        home_msg = monitor.wait(lambda m: m.get("HOME_POSITION"), w(180), "HOME_POSITION")
        home = (home_msg.latitude * 1e-7, home_msg.longitude * 1e-7, home_msg.altitude * 1e-3)
        assert distance(home[0], home[1], HOME[0], HOME[1]) < 5.0, home_msg
        monitor.wait(
            lambda m: m.get("GPS_RAW_INT") and m.get("GPS_RAW_INT").fix_type >= 3,
            w(60),
            "GPS 3D fix",
        )

        def until_mode(mode: str, what: str) -> None:
            """Ask for a mode until the vehicle is in it (refused while it settles)."""
            for _ in range(30):
                mp.send(f"mode {mode.lower()}")
                try:
                    monitor.wait(
                        lambda m: m.custom_mode() == COPTER_MODE[mode], w(5), what
                    )
                    return
                except AssertionError:
                    continue
            raise AssertionError(f"{what}: refused 30 times; {monitor.summary()}")

        until_mode("GUIDED", "mode GUIDED")
        for _ in range(30):  # arming is refused until the EKF has a position estimate
            mp.mark()
            mp.send("arm throttle")
            try:
                monitor.wait(lambda m: m.armed(), w(5), "armed")
                break
            except AssertionError:
                continue
        else:
            raise AssertionError(f"arm throttle refused 30 times; {mp.recent()}")
        mp.expect(r"\bARMED\b", w(10), "ARMED announced")

        mp.mark()
        mp.send("takeoff 10")
        mp.expect(r"COMMAND_ACK: NAV_TAKEOFF: ACCEPTED", w(10), "takeoff accepted")
        monitor.wait(lambda m: m.positions and m.positions[-1][2] > 9.0, w(60), "climb to 10 m")

        def reach(lat, lon, alt, what, radius=2.0):
            monitor.wait(
                lambda m: m.positions
                and distance(m.positions[-1][0], m.positions[-1][1], lat, lon) < radius
                and abs(m.positions[-1][2] - alt) < 1.5,
                w(90),
                what,
            )

        lat, lon = offset(home[0], home[1], 20.0, 15.0)
        mp.mark()
        mp.send(f"guided {lat:.7f} {lon:.7f} 15")
        mp.expect(r"COMMAND_ACK: DO_REPOSITION: ACCEPTED", w(10), "guided (DO_REPOSITION)")
        reach(lat, lon, 15.0, "reach the DO_REPOSITION target")

        lat, lon = offset(home[0], home[1], 25.0, -10.0)
        mp.send("set guided_use_reposition 0")
        mp.mark()
        mp.send(f"guided {lat:.7f} {lon:.7f} 18")
        mp.expect(r"MISSION_ACK: TYPE_MISSION: ACCEPTED", w(10), "guided (MISSION_ITEM_INT)")
        reach(lat, lon, 18.0, "reach the guided MISSION_ITEM_INT target")

        # ArduPilot keeps only the sign of a NAV_LAND's param 4 (it answers -1 or 1), so the
        # landing says 1 to come back as sent.
        items = [
            (MAV_CMD_NAV_WAYPOINT, *offset(home[0], home[1], 35.0, 10.0), 15.0, 0.0),
            (MAV_CMD_NAV_WAYPOINT, *offset(home[0], home[1], 35.0, -20.0), 18.0, 0.0),
            (MAV_CMD_NAV_WAYPOINT, *offset(home[0], home[1], 5.0, -25.0), 15.0, 0.0),
            (MAV_CMD_NAV_LAND, *offset(home[0], home[1], -10.0, -10.0), 0.0, 1.0),
        ]
        sent_file = tmp_path / "mission.txt"
        write_wpl(sent_file, home, items)
        mp.mark()
        mp.send(f"wp load {sent_file}")
        mp.expect(r"MISSION_ACK: TYPE_MISSION: ACCEPTED", w(30), "wp load")

        flown_from = len(monitor.positions)
        until_mode("AUTO", "mode AUTO")
        monitor.wait(lambda m: not m.armed(), w(300), "fly the mission, land and disarm")
        track = monitor.positions[flown_from:]
        closest = [
            min(distance(p[0], p[1], lat, lon) for p in track) for _, lat, lon, _, _ in items
        ]
        assert all(d < 5.0 for d in closest), f"closest approach per item {closest} m"
        last = track[-1]
        assert distance(last[0], last[1], items[-1][1], items[-1][2]) < 3.0, last
        assert abs(last[2]) < 1.0, last

        start = mp.mark()
        mp.send("wp list")
        mp.expect(r"Saved waypoints to", w(30), "wp list")
        # `wp list` prints each item at full precision (its saved file has only 6 decimals)
        got = [parse_listed(m) for m in map(LISTED.search, mp.output(start)) if m]
        assert len(got) == len(items) + 1, f"{len(got)} items back, sent {len(items) + 1}"
        assert distance(got[0]["x"], got[0]["y"], home[0], home[1]) < 5.0, got[0]
        for (command, lat, lon, alt, p4), b in zip(items, got[1:], strict=True):
            assert b["command"] == command and SAME_FRAME.get(b["frame"], b["frame"]) == 3, b
            assert b["x"] == pytest.approx(lat, abs=1.5e-7), (lat, b)
            assert b["y"] == pytest.approx(lon, abs=1.5e-7), (lon, b)
            assert b["z"] == pytest.approx(alt, abs=0.01), (alt, b)
            assert b["params"] == pytest.approx([0.0, 0.0, 0.0, p4], abs=0.01), b
            assert b["autocontinue"] == 1, b
    finally:
        monitor.close()
    said = mp.output()
    assert not alarms(said), f"MAVProxy announced: {alarms(said)}"
    if "ARMING_CHECK" in arming:
        assert not [line for line in said if "Arming checks disabled" in line]
    vehicle.alive()
