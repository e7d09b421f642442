"""Speed of the MAVLink vehicle driver.

1. Decode rate: pre-encoded telemetry (the mix an autopilot streams: ATTITUDE,
   LOCAL_POSITION_NED, GLOBAL_POSITION_INT, DISTANCE_SENSOR, SYS_STATUS, ... with HEARTBEATs)
   is written into an in-memory link and the driver's ``poll()`` decodes it into state
   snapshots, in its normal bounded batches. Target: >= 20,000 messages/s.
2. Lockstep flight: driver + embedded SITL (ArduPilot personality, all telemetry at nominal
   rates, 20 Hz ticks) fly take-off to 10 m, a goto 100 m away and a landing; printed as
   simulated seconds per wall second (how many times faster than real time), plus the
   driver's share of the tick.

Run: .venv/bin/python benchmarks/bench_driver.py
"""

from __future__ import annotations

import math
import time

import _checkout  # noqa: F401  (this checkout's packages first)
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.clock import SimClock
from autonomy.vehicle import MavlinkVehicle, VehicleLinkSettings, connect
from autonomy.vehicle.connection import MemoryTransport
from sitl.link import MemoryLink

DECODE_TARGET = 20_000.0
MESSAGES = 200_000
DT = 0.05


def _telemetry(n: int) -> bytes:
    """``n`` packets of an autopilot's telemetry mix, already encoded."""
    mav = mavlink.MAVLink(None, 1, 1)
    down = mavlink.MAV_SENSOR_ROTATION_PITCH_270
    mix = [
        mav.heartbeat_encode(2, 3, 217, 4, 4),
        mav.attitude_encode(0, 0.01, -0.02, 1.2, 0.0, 0.0, 0.1),
        mav.local_position_ned_encode(0, 10.0, 20.0, -30.0, 1.0, 2.0, 0.1),
        mav.global_position_int_encode(0, 473977420, 85455940, 518000, 30000, 100, 200, 10, 9000),
        mav.distance_sensor_encode(0, 20, 4000, 3000, 0, 0, down, 0),
        mav.attitude_encode(0, 0.01, -0.02, 1.2, 0.0, 0.0, 0.1),
        mav.local_position_ned_encode(0, 10.0, 20.0, -30.0, 1.0, 2.0, 0.1),
        mav.sys_status_encode(0, 0, 0, 200, 15000, 1800, 80, 0, 0, 0, 0, 0, 0),
        mav.extended_sys_state_encode(0, 2),
        mav.gps_raw_int_encode(0, 3, 473977420, 85455940, 518000, 80, 120, 500, 9000, 12),
    ]
    return b"".join(mix[i % len(mix)].pack(mav) for i in range(n))


def bench_decode() -> float:
    data = _telemetry(MESSAGES)
    clock = SimClock()
    link = MemoryLink()
    vehicle = MavlinkVehicle(
        MemoryTransport(link.gcs), clock, settings=VehicleLinkSettings(max_backlog_bytes=len(data))
    )
    link.vehicle.read()  # our first HEARTBEAT
    link.vehicle.write(data)
    start = time.perf_counter()
    cpu_start = time.thread_time()
    polls = 0
    while vehicle.stats.messages < MESSAGES:
        clock.advance(0.001)
        vehicle.poll()
        polls += 1
    elapsed = time.perf_counter() - start
    cpu = time.thread_time() - cpu_start
    vehicle.close()
    rate = MESSAGES / elapsed
    print("1. decode rate (in-memory link, pre-encoded telemetry mix)")
    print(
        f"   {MESSAGES} messages in {elapsed:.3f} s wall ({cpu:.3f} s CPU) over {polls} polls "
        f"({vehicle.settings.max_messages_per_poll} per poll)"
    )
    verdict = "OK" if rate >= DECODE_TARGET else "BELOW TARGET"
    print(
        f"   {rate:,.0f} messages/s wall, {MESSAGES / cpu:,.0f} per CPU second "
        f"(target >= {DECODE_TARGET:,.0f}/s: {verdict})"
    )
    return rate


def bench_lockstep_flight() -> float:
    clock = SimClock()
    streams = dict(VehicleLinkSettings().streams)
    streams.update(GLOBAL_POSITION_INT=10.0, BATTERY_STATUS=1.0)  # what a GCS also shows
    vehicle = connect("sim://ardupilot", clock, settings=VehicleLinkSettings(streams=streams))
    sitl = vehicle.sitl
    poll_time = 0.0
    ticks = 0

    def run(condition, timeout: float) -> None:
        nonlocal poll_time, ticks
        end = clock.now() + timeout
        while clock.now() < end:
            sitl.step(DT)
            clock.advance(DT)
            t0 = time.perf_counter()
            state = vehicle.poll()
            poll_time += time.perf_counter() - t0
            ticks += 1
            if condition(state):
                return
        raise RuntimeError(f"flight did not finish a phase: {vehicle.state}")

    start = time.perf_counter()
    run(lambda s: s.prearm_ok, 60)
    handle = vehicle.takeoff(10.0)
    run(lambda s: handle.done and s.position[2] > 9.7, 60)
    handle = vehicle.goto(100.0, 0.0, 10.0)
    run(lambda s: math.hypot(s.position[0] - 100.0, s.position[1]) < 0.5, 120)
    handle = vehicle.land()
    run(lambda s: not s.armed, 120)
    wall = time.perf_counter() - start
    sim = clock.now()
    messages = vehicle.stats.messages
    vehicle.close()
    speedup = sim / wall
    print("2. lockstep flight through driver + embedded SITL (take-off 10 m, goto 100 m, land)")
    print(
        f"   {sim:.1f} s simulated in {wall:.2f} s wall, {ticks} ticks of {DT * 1000:.0f} ms, "
        f"{messages} messages decoded"
    )
    print(
        f"   {speedup:,.0f}x faster than real time; driver poll {poll_time / ticks * 1e6:.0f} us "
        f"per tick ({100 * poll_time / wall:.0f}% of the loop)"
    )
    return speedup


if __name__ == "__main__":
    bench_decode()
    bench_lockstep_flight()
