"""Flights through the driver against the embedded SITL, in lockstep over the in-memory link
(and once over UDP on 127.0.0.1)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.clock import SimClock
from autonomy.vehicle import MavlinkVehicle, connect
from autonomy.vehicle.connection import MemoryTransport
from autonomy.vehicle.tlog import SIM_EPOCH
from behaviors.ports import CommandStatus, LandedState
from sitl import Sitl
from sitl.link import MemoryLink
from sitl.transports import TcpServer, UdpEndpoint

DT = 0.05


class Lockstep:
    """The runner's loop: sitl.step(dt); clock.advance(dt); vehicle.poll()."""

    def __init__(self, vehicle: MavlinkVehicle, sitl: Sitl, clock: SimClock) -> None:
        self.vehicle, self.sitl, self.clock = vehicle, sitl, clock
        self.on_tick = None

    def tick(self):
        self.sitl.step(DT)
        self.clock.advance(DT)
        if self.on_tick is not None:
            self.on_tick()
        return self.vehicle.poll()

    def until(self, condition, timeout: float, what: str):
        end = self.clock.now() + timeout
        while self.clock.now() < end:
            state = self.tick()
            if condition(state):
                return state
        raise AssertionError(f"{what}: not reached in {timeout} s; last state {state}")

    def done(self, handle, timeout: float = 10.0):
        self.until(lambda s: handle.done, timeout, handle.name)
        return handle


def horizontal_distance(state, x: float, y: float) -> float:
    return math.hypot(state.position[0] - x, state.position[1] - y)


@pytest.fixture(params=["ardupilot", "px4"])
def flight(request):
    clock = SimClock()
    vehicle = connect(f"sim://{request.param}", clock)
    yield Lockstep(vehicle, vehicle.sitl, clock)
    vehicle.close()


def test_takeoff_goto_land_disarmed(flight):
    v = flight.vehicle
    flight.until(lambda s: s.prearm_ok, 30, "prearm checks")
    assert v.state.autopilot == flight.sitl.personality
    assert v.state.landed_state is LandedState.ON_GROUND and not v.state.armed

    takeoff = flight.done(v.takeoff(10.0))
    assert takeoff.status is CommandStatus.ACCEPTED, takeoff.reason
    s = flight.until(lambda s: s.position[2] > 9.5, 30, "climb to 10 m")
    assert s.armed and s.landed_state is not LandedState.ON_GROUND

    goto = flight.done(v.goto(30.0, -20.0, 12.0))
    assert goto.status is CommandStatus.ACCEPTED, goto.reason
    assert v.state.mode in ("GUIDED", "OFFBOARD")
    s = flight.until(lambda s: horizontal_distance(s, 30.0, -20.0) < 0.5, 60, "goto")
    # The driver's ENU position is the simulator's truth (frames converted once, correctly).
    truth = flight.sitl.truth
    assert s.position == pytest.approx(truth.position, abs=0.6)
    assert math.cos(s.yaw - truth.yaw) == pytest.approx(1.0, abs=1e-3)
    flight.until(lambda s: abs(s.position[2] - 12.0) < 0.3, 20, "reach 12 m")

    land = flight.done(v.land())
    assert land.status is CommandStatus.ACCEPTED, land.reason
    assert v.state.mode in ("LAND", "AUTO.LAND")
    s = flight.until(lambda s: not s.armed and s.landed_state is LandedState.ON_GROUND, 90, "land")
    assert horizontal_distance(s, 30.0, -20.0) < 1.5
    assert abs(s.position[2]) < 0.2
    assert not flight.sitl.truth.crashed


def test_arm_denied_before_settling(flight):
    v = flight.vehicle
    flight.until(lambda s: not s.link_lost, 5, "link up")
    assert not v.state.prearm_ok
    handle = flight.done(v.arm())
    assert handle.status is CommandStatus.DENIED
    assert handle.reason.startswith(("PreArm:", "Preflight Fail:")), handle.reason
    assert not v.state.armed
    flight.until(lambda s: s.prearm_ok, 30, "prearm checks")
    again = flight.done(v.arm())
    assert again.status is CommandStatus.ACCEPTED and v.state.armed


def test_operator_mode_change_on_a_second_link(flight):
    v = flight.vehicle
    flight.until(lambda s: s.prearm_ok, 30, "prearm checks")
    flight.done(v.takeoff(8.0))
    flight.until(lambda s: s.position[2] > 7.5, 30, "climb")
    flight.done(v.goto(50.0, 0.0, 8.0))
    flight.until(lambda s: s.position[0] > 5.0, 30, "on the way")

    # A second ground station (system 254) on its own link switches to a hold mode.
    other = MemoryLink()
    flight.sitl.attach(other.vehicle)
    operator = mavlink.MAVLink(other.gcs, 254, 190)
    hold = "LOITER" if flight.sitl.personality == "ardupilot" else "POSCTL"
    operator.heartbeat_send(mavlink.MAV_TYPE_GCS, mavlink.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    if flight.sitl.personality == "ardupilot":
        params = (1, 5, 0)
    else:
        params = (1, 3, 0)
    operator.command_long_send(1, 1, mavlink.MAV_CMD_DO_SET_MODE, 0, *params, 0, 0, 0, 0)
    s = flight.until(lambda s: s.mode == hold, 5, "operator's mode")
    change = v.mode_changes[-1]
    assert (change.new, change.requested) == (hold, False)
    # Our target is no longer pushed: the vehicle stops short of x = 50 m.
    s = flight.until(lambda s: math.hypot(*s.velocity[:2]) < 0.1, 20, "vehicle stops")
    for _ in range(100):
        s = flight.tick()
    assert s.mode == hold and s.position[0] < 45.0


def test_link_loss_is_detected_and_commands_fail_fast(flight):
    v = flight.vehicle
    flight.until(lambda s: s.prearm_ok, 30, "prearm checks")
    pending = v.set_mode("POSCTL")  # POSHOLD on ArduPilot; neither starts in it
    # The simulator stops talking: the clock goes on, nothing arrives.
    for _ in range(int(3.5 / DT)):
        flight.clock.advance(DT)
        s = v.poll()
    assert s.link_lost and s.heartbeat_age > 3.0
    assert pending.status is CommandStatus.TIMED_OUT and "link lost" in pending.reason
    late = v.takeoff(10.0)
    assert late.status is CommandStatus.TIMED_OUT and "link" in late.reason
    # The simulator resumes (it was paused, so its clock lags ours: that is fine).
    s = flight.until(lambda s: not s.link_lost, 5, "link back")
    assert not s.link_lost


def test_corrupt_bytes_on_the_link_are_survived():
    clock = SimClock()
    sitl = Sitl(autopilot="ardupilot")
    link = MemoryLink()
    sitl.attach(link.vehicle)
    vehicle = MavlinkVehicle(MemoryTransport(link.gcs), clock, sitl=sitl, owns_sitl=True)
    flight = Lockstep(vehicle, sitl, clock)
    rng = np.random.default_rng(7)

    def inject():  # garbage between the simulator's packets, every tick
        link.vehicle.write(rng.bytes(int(rng.integers(1, 60))))

    flight.on_tick = inject
    try:
        flight.until(lambda s: s.prearm_ok, 30, "prearm checks")
        flight.done(vehicle.takeoff(5.0))
        s = flight.until(lambda s: s.position[2] > 4.6, 30, "climb through noise")
        assert s.armed
        assert vehicle.stats.corrupt_bytes > 1000
    finally:
        vehicle.close()


@pytest.mark.parametrize("scheme", ["udpout", "tcp"])
def test_flight_over_a_socket_with_a_telemetry_log(tmp_path, scheme):
    clock = SimClock()
    sitl = Sitl(autopilot="ardupilot")
    server = UdpEndpoint() if scheme == "udpout" else TcpServer()
    host, port = server.address
    tlog = tmp_path / "flight.tlog"
    vehicle = connect(f"{scheme}:{host}:{port}", clock, tlog_path=tlog)
    flight = Lockstep(vehicle, sitl, clock)
    if scheme == "udpout":
        sitl.attach(server)
    else:
        flight.on_tick = lambda: [sitl.attach(c) for c in server.accept()]
    try:
        flight.until(lambda s: s.prearm_ok, 30, f"prearm checks over {scheme}")
        flight.done(vehicle.takeoff(5.0))
        flight.until(lambda s: s.position[2] > 4.6, 30, "climb")
        flight.done(vehicle.land())
        flight.until(lambda s: not s.armed, 60, "land and disarm")
    finally:
        vehicle.close()
        sitl.close()
        server.close()

    log = mavutil.mavlink_connection(str(tlog))
    seen, stamps = set(), []
    while (msg := log.recv_match()) is not None:
        seen.add((msg.get_srcSystem(), msg.get_type()))
        stamps.append(msg._timestamp)
    assert (255, "COMMAND_LONG") in seen and (1, "COMMAND_ACK") in seen
    assert (1, "LOCAL_POSITION_NED") in seen and (255, "HEARTBEAT") in seen
    assert stamps == sorted(stamps)
    # Live links are stamped with wall time at connect + clock time.
    assert stamps[-1] - stamps[0] == pytest.approx(clock.now(), abs=0.2)


def test_sim_link_log_is_stamped_in_simulated_time(tmp_path):
    clock = SimClock()
    tlog = tmp_path / "sim.tlog"
    vehicle = connect("sim://", clock, tlog_path=tlog)
    flight = Lockstep(vehicle, vehicle.sitl, clock)
    for _ in range(40):
        flight.tick()
    vehicle.close()
    log = mavutil.mavlink_connection(str(tlog))
    stamps = []
    while (msg := log.recv_match()) is not None:
        stamps.append(msg._timestamp)
    assert stamps[0] == SIM_EPOCH
    assert stamps[-1] == pytest.approx(SIM_EPOCH + 2.0)


def test_closing_the_vehicle_detaches_it_from_a_shared_simulator():
    clock = SimClock()
    sitl = Sitl(autopilot="px4")
    first = connect("sim://", clock, sitl=sitl)
    first.close()
    second = connect("sim://", clock, sitl=sitl)
    flight = Lockstep(second, sitl, clock)
    try:
        flight.until(lambda s: not s.link_lost, 5, "second vehicle hears the simulator")
        assert len(sitl.server.links) == 1
    finally:
        second.close()
        sitl.close()


def test_velocity_then_hold(flight):
    v = flight.vehicle
    flight.until(lambda s: s.prearm_ok, 30, "prearm checks")
    flight.done(v.takeoff(6.0))
    flight.until(lambda s: s.position[2] > 5.6, 30, "climb")

    fly = flight.done(v.set_velocity(0.0, 3.0, 0.0))  # north at 3 m/s
    assert fly.status is CommandStatus.ACCEPTED, fly.reason
    s = flight.until(lambda s: s.velocity[1] > 2.8, 10, "speed up northwards")
    assert abs(s.velocity[0]) < 0.3
    start_y = s.position[1]
    for _ in range(int(3.0 / DT)):
        s = flight.tick()
    assert s.position[1] - start_y == pytest.approx(9.0, abs=1.0)

    stop = flight.done(v.hold())
    assert stop.status is CommandStatus.ACCEPTED, stop.reason
    assert v.state.mode in ("GUIDED", "AUTO.LOITER")
    s = flight.until(lambda s: math.hypot(*s.velocity) < 0.05, 15, "stop")
    here = s.position
    for _ in range(int(5.0 / DT)):
        s = flight.tick()
    assert s.position == pytest.approx(here, abs=0.2)


def test_position_estimate_waits_for_the_ekf_and_guided_is_refused_before_it():
    # ArduPilot: prearm checks pass (for STABILIZE) before the EKF has an absolute position;
    # GUIDED is refused until then. The driver reads it from EKF_STATUS_REPORT.
    from sitl import SitlSettings

    clock = SimClock()
    sitl = Sitl(SitlSettings(arming_settle_time=3.0, position_settle_time=8.0))
    vehicle = connect("sim://", clock, sitl=sitl)
    flight = Lockstep(vehicle, sitl, clock)
    try:
        state = flight.until(lambda s: s.prearm_ok, 5, "prearm checks")
        assert not state.position_estimate and state.home is None
        early = flight.done(vehicle.set_mode("GUIDED"))
        assert early.status is CommandStatus.DENIED
        assert "requires position" in early.reason
        state = flight.until(lambda s: s.position_estimate, 10, "position estimate")
        assert clock.now() >= 8.0
        flight.until(lambda s: s.home is not None, 3, "home")
        takeoff = flight.done(vehicle.takeoff(5.0), timeout=15)
        assert takeoff.status is CommandStatus.ACCEPTED, takeoff.reason
    finally:
        vehicle.close()
