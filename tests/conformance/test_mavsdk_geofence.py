"""MAVSDK-Python's geofence, enforced: an inclusion polygon around home uploaded with
``geofence.upload_geofence``, then a breach.

PX4 acts on an uploaded fence at its default GF_ACTION (2, Hold): flown out of it by offboard
velocity, it says "Geofence violation: ..." and leaves OFFBOARD for Hold. ArduPilot acts only
once the fence is enabled (FENCE_ENABLE, default 0): the vehicle goes out first (an enabled
fence would refuse the target, and AVOID_ENABLE stop it at the fence), the fence is enabled,
and FENCE_ACTION 1 returns it home ("Polygon fence breached").
"""

from __future__ import annotations

import asyncio

import pytest
from conformance_support import (
    HOME,
    arm_and_takeoff,
    collect_status_texts,
    connect,
    distance,
    mode,
    offset,
    until,
    within,
)
from mavsdk.geofence import FenceType, GeofenceData, Point, Polygon
from mavsdk.offboard import VelocityNedYaw

pytestmark = pytest.mark.timeout(400)

SPEEDUP = 5.0  # MAVSDK streams offboard setpoints at 20 Hz of wall time
HALF = 30.0  # m: the fence is a square this far either side of home
CRUISE = 10.0


@pytest.mark.parametrize("autopilot", ["ardupilot", "px4"])
def test_mavsdk_geofence_breach(start_vehicle, mavsdk_server, autopilot):
    vehicle = start_vehicle(autopilot, speedup=SPEEDUP)
    w = vehicle.wall

    async def scenario():
        drone = await connect(vehicle, mavsdk_server)
        tel, action = drone.telemetry, drone.action
        collector, texts = collect_status_texts(tel)
        if autopilot == "ardupilot":  # ArduPilot streams nothing until asked
            for rate, hz in ((tel.set_rate_position, 10.0), (tel.set_rate_velocity_ned, 10.0),
                             (tel.set_rate_health, 2.0), (tel.set_rate_home, 1.0)):
                await within(rate(hz), w(10), rate.__name__)
        await until(tel.health(), lambda h: h.is_global_position_ok, w(60), "position ok")
        corners = [offset(HOME[0], HOME[1], n, e) for n, e in
                   ((-HALF, -HALF), (-HALF, HALF), (HALF, HALF), (HALF, -HALF))]  # fmt: skip
        fence = GeofenceData(
            [Polygon([Point(lat, lon) for lat, lon in corners], FenceType.INCLUSION)], []
        )
        await within(drone.geofence.upload_geofence(fence), w(20), "upload geofence")
        await within(action.set_takeoff_altitude(CRUISE), w(20), "takeoff altitude")
        await arm_and_takeoff(drone, vehicle)
        await until(tel.position(), lambda p: p.relative_altitude_m > CRUISE - 1.0, w(60),
                    "climb")  # fmt: skip

        def east(p) -> float:
            return distance(HOME[0], HOME[1], p.latitude_deg, p.longitude_deg)

        if autopilot == "px4":
            offboard = drone.offboard
            await within(offboard.set_velocity_ned(VelocityNedYaw(0, 3.0, 0, 90)), w(10), "vel")
            await within(offboard.start(), w(10), "offboard start")
            await mode(tel, "OFFBOARD", w(10))
            await mode(tel, "HOLD", w(60))
            where = await until(tel.position(), lambda p: True, w(10), "position")
            assert HALF - 1.0 < east(where) < HALF + 10.0, east(where)
            await within(offboard.stop(), w(10), "offboard stop")
            expected = "Geofence violation"
        else:
            lat, lon = offset(HOME[0], HOME[1], 0.0, HALF + 25.0)
            here = await until(tel.position(), lambda p: True, w(10), "position")
            await within(action.goto_location(lat, lon, here.absolute_altitude_m, float("nan")),
                         w(10), "goto")  # fmt: skip
            await until(tel.position(), lambda p: east(p) > HALF + 20.0, w(60), "out of fence")
            await within(drone.param.set_param_int("FENCE_ENABLE", 1), w(10), "FENCE_ENABLE")
            await mode(tel, "RETURN_TO_LAUNCH", w(20))
            expected = "Polygon fence breached"
        end = asyncio.get_running_loop().time() + w(10)
        while not any(t.startswith(expected) for t in texts):
            assert asyncio.get_running_loop().time() < end, f"no {expected!r} in {texts}"
            await asyncio.sleep(0.1)
        collector.cancel()

    asyncio.run(scenario())
    vehicle.alive()
