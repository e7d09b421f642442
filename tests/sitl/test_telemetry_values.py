"""The streams the SITL packs from their values (sitl.copter.telemetry.Telemetry.values,
FastMAVLink.send_values) are byte for byte the packets pymavlink makes of the same
messages, over a flight with wind, climbs, turns and a landing."""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from sitl import MemoryLink, Sitl
from sitl.copter.gcs import MiniGcs
from sitl.copter.settings import SitlSettings

DT = 0.05


class _Sink:
    def __init__(self) -> None:
        self.packets: list[bytes] = []

    def write(self, data: bytes) -> None:
        self.packets.append(bytes(data))


def test_values_pack_as_the_messages_do():
    settings = SitlSettings.model_validate({"wind": {"speed": 4.0, "gust_sigma": 1.0}})
    sim = Sitl(settings, seed=3)
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)
    gcs.keep = False
    gcs.heartbeat()
    telemetry = sim.server.telemetry
    sink = _Sink()
    fast = sim.server.links[0].mav.__class__(sink, srcSystem=1, srcComponent=1)
    plain = mavlink.MAVLink(sink, srcSystem=1, srcComponent=1)
    compared = 0

    def compare() -> None:
        nonlocal compared
        for msgid, values in telemetry.values.items():
            fast.seq = plain.seq = compared % 256
            fast.send_values(msgid, values())
            plain.send(telemetry.builders[msgid]())
            assert sink.packets[-2] == sink.packets[-1], mavlink.mavlink_map[msgid].msgname
            compared += 1

    for _ in range(int(sim.settings.arming_settle_time / DT) + 2):
        sim.step(DT)
        compare()
    gcs.set_mode(4)
    gcs.arm()
    gcs.takeoff(12.0)
    plan = [(8.0, None), (15.0, (30.0, -20.0, -25.0)), (15.0, (-10.0, 5.0, -3.0))]
    for seconds, target in plan:
        if target is not None:
            gcs.goto_ned(*target)
        for _ in range(int(seconds / DT)):
            sim.step(DT)
            gcs.poll()
            compare()
    gcs.set_mode(9)  # LAND
    for _ in range(int(20.0 / DT)):
        sim.step(DT)
        gcs.poll()
        compare()
    assert sim.truth.landed
    assert compared > 2000
