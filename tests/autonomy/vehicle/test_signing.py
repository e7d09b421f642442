"""MAVLink 2 signing between the driver and the embedded SITL: a mission's key signs both
ends of a sim:// flight; a peer without the key, or with another one, is refused."""

from __future__ import annotations

from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.clock import SimClock
from autonomy.config import apply_overrides, load_mission
from autonomy.runner import fly
from autonomy.vehicle import connect, signing_key_from_text
from sitl import MemoryLink
from sitl.copter.gcs import MiniGcs

DEMO = Path(__file__).resolve().parents[3] / "missions" / "demo.yaml"


def test_a_signed_lockstep_flight_lands_with_no_bad_signature():
    mission = apply_overrides(load_mission(DEMO), {"vehicle.signing_key": "correct horse"})
    result = fly(mission)
    assert result.outcome == "landed"
    link = result.summary["link"]
    assert link["bad_signature"] == 0 and link["messages_received"] > 1000


def test_the_signed_simulator_refuses_an_unsigned_ground_station_and_a_wrong_key():
    key = signing_key_from_text("correct horse")
    clock = SimClock()
    vehicle = connect("sim://", clock, signing_key=key)
    sim = vehicle.sitl
    unsigned = MemoryLink()
    sim.attach(unsigned.vehicle)
    stranger = MiniGcs(unsigned.gcs)
    wrong = MemoryLink()
    sim.attach(wrong.vehicle)
    impostor = MiniGcs(wrong.gcs)
    impostor.mav.signing.secret_key = signing_key_from_text("wrong key")
    impostor.mav.signing.sign_outgoing = True
    impostor.mav.signing.timestamp = 4 * 10**13
    impostor.mav.signing.allow_unsigned_callback = lambda mav, msg_id: True
    try:
        for gcs in (stranger, impostor):
            gcs.heartbeat()
            gcs.command(mavlink.MAV_CMD_REQUEST_MESSAGE, mavlink.MAVLINK_MSG_ID_AUTOPILOT_VERSION)
        for _ in range(40):
            sim.step(0.1)
            clock.advance(0.1)
            vehicle.poll()
            stranger.poll()
            impostor.poll()
        assert not vehicle.state.link_lost  # the driver, holding the key, hears the vehicle
        assert vehicle.stats.bad_signature == 0
        for gcs in (stranger, impostor):
            assert gcs.acks(mavlink.MAV_CMD_REQUEST_MESSAGE) == []  # refused, unanswered
        refused = [link.refused_unsigned for link in sim.server.links[1:]]
        assert all(count >= 2 for count in refused)
    finally:
        vehicle.close()
