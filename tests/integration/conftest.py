"""Helpers for flights against real autopilot SITLs (ArduPilot, PX4) in real time.

These tests are skipped unless an environment variable names the SITL binary; they start it
in a temporary folder, connect the driver through pymavlink, fly, and stop the process.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

from autonomy.clock import WallClock
from autonomy.vehicle import MavlinkVehicle, connect


def wait_for_tcp(host: str, port: int, timeout: float) -> None:
    """Wait until something accepts TCP connections on (host, port)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        with socket.socket() as probe:
            probe.settimeout(0.5)
            if probe.connect_ex((host, port)) == 0:
                return
        time.sleep(0.2)
    raise AssertionError(f"nothing listens on {host}:{port} after {timeout} s")


class LiveFlight:
    """Polls a live vehicle at ``rate`` Hz of wall time until conditions hold."""

    def __init__(self, vehicle: MavlinkVehicle, rate: float = 50.0) -> None:
        self.vehicle = vehicle
        self.period = 1.0 / rate

    def until(self, condition, timeout: float, what: str):
        end = self.vehicle.clock.now() + timeout
        state = self.vehicle.poll()
        while self.vehicle.clock.now() < end:
            state = self.vehicle.poll()
            if condition(state):
                return state
            time.sleep(self.period)
        raise AssertionError(f"{what}: not reached in {timeout} s; last state {state}")

    def done(self, handle, timeout: float = 15.0):
        self.until(lambda s: handle.done, timeout, handle.name)
        return handle


def start_process(
    argv: list[str], cwd: Path, env: dict[str, str] | None = None
) -> subprocess.Popen:
    log = open(cwd / "sitl.log", "wb")  # the child keeps it open; closed when it exits
    return subprocess.Popen(
        argv,
        cwd=cwd,
        env={**os.environ, **(env or {})},
        stdin=subprocess.DEVNULL,
        stdout=log,
        stderr=subprocess.STDOUT,
        start_new_session=True,
    )


def stop_process(proc: subprocess.Popen) -> None:
    """Stop the SITL we started (its own process group, by its id)."""
    if proc.poll() is None:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(timeout=10)


def connect_live(url: str, **kwargs) -> MavlinkVehicle:
    return connect(url, WallClock(), **kwargs)


@pytest.fixture
def start_sitl(tmp_path):
    """start_sitl(argv, env=None, tcp_port=None): run a SITL binary in a temporary folder
    (output in sitl.log there), optionally wait for its TCP port; stopped after the test."""
    started: list[subprocess.Popen] = []

    def start(argv: list[str], env: dict[str, str] | None = None, tcp_port: int | None = None):
        proc = start_process(argv, tmp_path, env)
        started.append(proc)
        if tcp_port is not None:
            wait_for_tcp("127.0.0.1", tcp_port, 60)
        return proc

    yield start
    for proc in started:
        stop_process(proc)


@pytest.fixture
def live_flight():
    made: list[MavlinkVehicle] = []

    def factory(url: str) -> LiveFlight:
        """Connect the driver to ``url`` on a wall clock."""
        vehicle = connect_live(url)
        made.append(vehicle)
        return LiveFlight(vehicle)

    yield factory
    for vehicle in made:
        vehicle.close()
