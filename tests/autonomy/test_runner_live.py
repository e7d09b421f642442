"""Live mode: the runner flies a SITL served over TCP in real time; Ctrl-C lands it."""

from __future__ import annotations

import _thread
import threading
from pathlib import Path

import pytest

from autonomy.config import apply_overrides, load_mission
from autonomy.runner import fly
from sitl import Sitl
from sitl.realtime import RealTimeRunner
from sitl.transports import TcpServer

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"
SPEEDUP = 8.0


@pytest.fixture
def served_sitl():
    """An embedded SITL served on 127.0.0.1 (ephemeral TCP port) at SPEEDUP x real time."""
    sitl = Sitl(autopilot="ardupilot")
    server = TcpServer("127.0.0.1", 0)
    runner = RealTimeRunner(sitl, tcp=[server], speedup=SPEEDUP)
    stop = threading.Event()
    thread = threading.Thread(target=runner.run, kwargs={"should_stop": stop.is_set},
                              daemon=True)
    thread.start()
    yield sitl, server.address[1]
    stop.set()
    thread.join(timeout=10)
    runner.close()


def test_ctrl_c_in_live_mode_lands_the_vehicle(served_sitl, tmp_path):
    sitl, port = served_sitl
    mission = apply_overrides(load_mission(DEMO), {
        "vehicle.connection": f"tcp:127.0.0.1:{port}",
        "time_limit": 120.0,
    })
    airborne = threading.Event()
    done = threading.Event()

    def interrupt_when_airborne():
        # Ctrl-C once the vehicle has climbed a few metres (read from the simulator).
        while not done.is_set():
            if sitl.truth.position[2] > 4.0:
                airborne.set()
                _thread.interrupt_main()
                return
            done.wait(0.05)

    watcher = threading.Thread(target=interrupt_when_airborne, daemon=True)
    watcher.start()
    try:
        result = fly(mission, out_dir=tmp_path, on_interrupt="land")
    finally:
        done.set()
        watcher.join(timeout=5)
    assert airborne.is_set()
    summary = result.summary
    assert summary["outcome"] == "aborted"
    assert summary["mode"] == "live" and summary["realtime_factor"] is None
    assert summary["stop_reason"].startswith("interrupted (land")
    truth = sitl.truth
    assert truth.landed and not truth.armed and not truth.crashed
    assert summary["touchdown"] is not None  # seen from the autopilot's landed state
    kinds = [e.get("event") for e in result.events if e["kind"] == "flight"]
    assert "land" in kinds and "touchdown" in kinds
