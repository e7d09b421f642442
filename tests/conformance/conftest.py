"""Fixtures of the conformance tests; the helpers live in support.py, importable as
``conformance_support`` (the suite uses --import-mode=importlib, which puts no test directory
on sys.path). See support.py for how to run these against ArduPilot's and PX4's own SITLs."""

import importlib.util
import sys
from pathlib import Path

import pytest

if "conformance_support" not in sys.modules:
    _spec = importlib.util.spec_from_file_location(
        "conformance_support", Path(__file__).with_name("support.py")
    )
    _module = importlib.util.module_from_spec(_spec)
    sys.modules["conformance_support"] = _module
    _spec.loader.exec_module(_module)

from conformance_support import (  # noqa: E402
    MavProxy,
    Vehicle,
    start_mavsdk_server,
    stop_process,
    tail,
)
from conformance_support import start_vehicle as _start_vehicle  # noqa: E402


@pytest.fixture
def start_vehicle(tmp_path):
    """start_vehicle("ardupilot"|"px4", px4_speedup=None, speedup=None) -> Vehicle, in a
    temporary folder; stopped (its whole process group) after the test. ``px4_speedup`` caps
    the speed-up of a real PX4 SITL (CONFORMANCE_PX4), ``speedup`` the embedded SITL's."""
    started: list[Vehicle] = []

    def start(
        autopilot: str, px4_speedup: float | None = None, speedup: float | None = None
    ) -> Vehicle:
        workdir = tmp_path / f"vehicle{len(started)}"
        workdir.mkdir()
        vehicle = _start_vehicle(autopilot, workdir, px4_speedup, speedup)
        started.append(vehicle)
        return vehicle

    yield start
    for vehicle in started:
        stop_process(vehicle.proc)
        print(f"--- {vehicle.name}, last lines:\n{tail(vehicle.log, 15)}")


@pytest.fixture
def mavsdk_server(tmp_path):
    """mavsdk_server(address) -> (host, grpc_port) of a mavsdk_server connected to
    ``address``; stopped after the test. ``mavsdk_server.processes`` lists their processes
    (a test may pause one to cut what it streams)."""
    started = []

    def start(address: str) -> tuple[str, int]:
        workdir = tmp_path / f"mavsdk{len(started)}"
        workdir.mkdir()
        proc, log, port = start_mavsdk_server(address, workdir)
        started.append((proc, log))
        start.processes.append(proc)
        return "127.0.0.1", port

    start.processes = []
    yield start
    for proc, log in started:
        stop_process(proc)
        print(f"--- mavsdk_server, last lines:\n{tail(log, 25)}")


@pytest.fixture
def mavproxy(tmp_path):
    """mavproxy(master, *extra_args) -> MavProxy; its state (logs, parameter files) goes to a
    temporary folder, never the repository; stopped after the test."""
    started: list[MavProxy] = []

    def start(master: str, *extra: str) -> MavProxy:
        proxy = MavProxy(master, tmp_path / f"mavproxy{len(started)}", list(extra))
        started.append(proxy)
        return proxy

    yield start
    for proxy in started:
        proxy.close()
        print(f"--- MAVProxy, last lines:\n{proxy.recent(limit=40)}")
