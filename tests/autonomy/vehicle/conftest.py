"""A scripted autopilot peer on an in-memory link, for driver tests that need exact control
over what the vehicle says (the embedded SITL is used for the flights)."""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.clock import SimClock
from autonomy.vehicle import MavlinkVehicle, VehicleLinkSettings
from autonomy.vehicle.connection import MemoryTransport
from sitl.link import MemoryLink


class _Sink:
    def __init__(self) -> None:
        self.data = bytearray()

    def write(self, buf: bytes) -> None:
        self.data += buf


class ScriptedPeer:
    """A fake autopilot: encodes what the test tells it to say, decodes what the driver sent."""

    def __init__(self, endpoint, system: int = 1, component: int = 1) -> None:
        self.endpoint = endpoint
        self.sink = _Sink()
        self.mav = mavlink.MAVLink(self.sink, system, component)
        self.parser = mavlink.MAVLink(None, 0, 0)
        self.parser.robust_parsing = True
        self.received: list = []

    def send(self, msg, *, flush: bool = True) -> None:
        self.mav.send(msg)
        if flush:
            self.flush()

    def flush(self) -> None:
        if self.sink.data:
            self.endpoint.write(bytes(self.sink.data))
            self.sink.data.clear()

    def heartbeat(self, custom_mode: int = 4, armed: bool = False, autopilot: int = 3) -> None:
        base = mavlink.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        if armed:
            base |= mavlink.MAV_MODE_FLAG_SAFETY_ARMED
        self.send(
            self.mav.heartbeat_encode(
                mavlink.MAV_TYPE_QUADROTOR, autopilot, base, custom_mode, mavlink.MAV_STATE_STANDBY
            )
        )

    def ack(self, command: int, result: int = mavlink.MAV_RESULT_ACCEPTED) -> None:
        self.send(self.mav.command_ack_encode(command, result, 0, 0, 255, 190))

    def text(self, text: str) -> None:
        self.send(self.mav.statustext_encode(mavlink.MAV_SEVERITY_CRITICAL, text.encode()))

    def drain(self) -> list:
        """Messages the driver sent since the last call."""
        msgs = self.parser.parse_buffer(self.endpoint.read()) or []
        msgs = [m for m in msgs if m.get_type() != "BAD_DATA"]
        self.received.extend(msgs)
        return msgs

    def commands(self, command: int | None = None) -> list:
        return [
            m
            for m in self.received
            if m.get_type() == "COMMAND_LONG" and (command is None or m.command == command)
        ]


class Rig:
    """Driver + scripted peer + simulated clock."""

    def __init__(self, **kwargs) -> None:
        self.clock = SimClock()
        self.link = MemoryLink()
        self.peer = ScriptedPeer(self.link.vehicle)
        settings = kwargs.pop("settings", VehicleLinkSettings())
        self.vehicle = MavlinkVehicle(
            MemoryTransport(self.link.gcs), self.clock, settings=settings, **kwargs
        )

    def tick(self, dt: float = 0.05):
        self.clock.advance(dt)
        state = self.vehicle.poll()
        self.peer.drain()
        return state

    def run(self, seconds: float, dt: float = 0.05, heartbeat=None):
        """Advance ``seconds``; the peer sends a heartbeat every second if given kwargs."""
        state = self.vehicle.state
        steps = int(round(seconds / dt))
        for i in range(steps):
            if heartbeat is not None and i % int(round(1.0 / dt)) == 0:
                self.peer.heartbeat(**heartbeat)
            state = self.tick(dt)
        return state


@pytest.fixture
def rig():
    r = Rig()
    yield r
    r.vehicle.close()


@pytest.fixture
def make_rig():
    made: list[Rig] = []

    def factory(**kwargs) -> Rig:
        r = Rig(**kwargs)
        made.append(r)
        return r

    yield factory
    for r in made:
        r.vehicle.close()
