"""Speed of the embedded SITL.

1. Lockstep flight: the SITL (ArduPilot personality) with all telemetry a driver uses
   requested at nominal ArduPilot-like rates (~52 messages/s of sim time), ticked at 20 Hz,
   flies take-off to 20 m, a goto 100 m away and a landing. The client sends real MAVLink
   commands and reads every byte; printed as simulated seconds per wall second (how many
   times faster than real time), once with the client only collecting the bytes (the SITL's
   own cost) and once with a pymavlink client parsing every message. Target: >= 200x.
2. Raw message rate: every streamed message requested at every step; messages packed per
   wall second.

Run: .venv/bin/python benchmarks/bench_sitl.py
"""

from __future__ import annotations

import time

import _checkout  # noqa: F401  (this checkout's packages first)
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl
from sitl.copter.gcs import MiniGcs

TARGET = 200.0
DT = 0.05
NOMINAL_HZ = {
    mavlink.MAVLINK_MSG_ID_ATTITUDE: 10,
    mavlink.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10,
    mavlink.MAVLINK_MSG_ID_LOCAL_POSITION_NED: 10,
    mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR: 10,
    mavlink.MAVLINK_MSG_ID_SYS_STATUS: 2,
    mavlink.MAVLINK_MSG_ID_EXTENDED_SYS_STATE: 2,
    mavlink.MAVLINK_MSG_ID_BATTERY_STATUS: 2,
    mavlink.MAVLINK_MSG_ID_GPS_RAW_INT: 2,
    mavlink.MAVLINK_MSG_ID_SYSTEM_TIME: 1,
    mavlink.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
}


class _ByteCounter:
    """A client that only collects the bytes (no parsing): the SITL's own cost."""

    def __init__(self, endpoint) -> None:
        self.endpoint = endpoint
        self.bytes = 0

    def poll(self) -> None:
        self.bytes += len(self.endpoint.read())


def flight(parse: bool) -> tuple[float, float, int, float]:
    """One lockstep mission; returns (sim seconds, wall seconds, messages, crashed?)."""
    sim = Sitl()
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)
    gcs.keep = False
    reader = gcs if parse else _ByteCounter(link.gcs)
    gcs.heartbeat()
    for msgid, hz in NOMINAL_HZ.items():
        gcs.set_interval(msgid, hz)
    phase = "settle"
    t0 = time.perf_counter()
    while phase != "done":
        sim.step(DT)
        reader.poll()
        truth = sim.truth if phase != "settle" else None
        if phase == "settle" and sim.time > sim.settings.arming_settle_time:
            gcs.set_mode(4)  # GUIDED
            gcs.arm()
            gcs.takeoff(20.0)
            phase = "climb"
        elif phase == "climb" and truth.position[2] > 19.8:
            gcs.goto_ned(0.0, 100.0, -20.0)
            phase = "cruise"
        elif phase == "cruise" and abs(truth.position[0] - 100.0) < 0.3:
            gcs.set_mode(9)  # LAND
            phase = "land"
        elif phase == "land" and not truth.armed:
            phase = "done"
        if sim.time > 600:
            raise RuntimeError(f"flight did not finish (phase {phase})")
    wall = time.perf_counter() - t0
    messages = link.vehicle and sim.server.links[0].mav.total_packets_sent
    return sim.time, wall, messages, sim.truth.crashed


def raw_rate(seconds: float = 60.0) -> tuple[float, int]:
    """Every stream at every step (20 Hz each): messages packed per wall second."""
    sim = Sitl()
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)
    gcs.heartbeat()
    for msgid in (*NOMINAL_HZ, mavlink.MAVLINK_MSG_ID_HEARTBEAT):
        gcs.set_interval(msgid, 1.0 / DT)
    sim.step(DT)
    mav = sim.server.links[0].mav
    start = mav.total_packets_sent
    t0 = time.perf_counter()
    while sim.time < seconds:
        sim.step(DT)
        link.gcs.read()
    wall = time.perf_counter() - t0
    sent = mav.total_packets_sent - start
    return sent / wall, sent


def main() -> None:
    print(f"lockstep flight (take-off 20 m, 100 m goto, land), {1 / DT:.0f} Hz ticks, "
          f"~{sum(NOMINAL_HZ.values()) + 1:.1f} msg/s of telemetry requested")
    for parse, label in ((False, "SITL only (bytes collected)"),
                         (True, "SITL + pymavlink client parsing")):
        sim_s, wall, messages, crashed = min(
            (flight(parse) for _ in range(3)), key=lambda r: r[1]
        )
        factor = sim_s / wall
        verdict = "ok" if factor >= TARGET else "BELOW TARGET"
        print(f"  {label:34s}: {sim_s:6.1f} sim s in {wall:6.3f} s wall = {factor:7.0f}x "
              f"real time ({verdict}, target {TARGET:.0f}x); {messages} messages"
              f"{', CRASHED' if crashed else ''}")
    rate, sent = raw_rate()
    print(f"raw telemetry: {rate:,.0f} messages/s packed ({sent} messages, 11 streams at "
          f"{1 / DT:.0f} Hz)")


if __name__ == "__main__":
    main()
