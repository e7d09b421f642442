"""Wall-clock pacing for the SITL when it runs standalone (QGroundControl, MAVProxy, a live
driver). This is the simulator's own clock, so it may sleep; the autonomy never does."""

from __future__ import annotations

import time
from collections.abc import Callable

from .transports import TcpServer, UdpEndpoint


class RealTimeRunner:
    """Steps a :class:`sitl.Sitl` at ``speedup`` times wall-clock speed, serving sockets.

    Args:
        sitl: the simulator.
        udp: UDP endpoints to serve (attached at once).
        tcp: TCP servers whose clients are attached as they connect.
        step: simulated seconds per step.
        speedup: simulated seconds per wall second (falls behind, never skips, if the CPU
            cannot keep up).
    """

    def __init__(
        self,
        sitl,
        *,
        udp: list[UdpEndpoint] | None = None,
        tcp: list[TcpServer] | None = None,
        step: float = 0.02,
        speedup: float = 1.0,
    ) -> None:
        if not step > 0:
            raise ValueError(f"step: must be > 0, got {step}")
        if not speedup > 0:
            raise ValueError(f"speedup: must be > 0, got {speedup}")
        self.sitl = sitl
        self.udp = list(udp or [])
        self.tcp = list(tcp or [])
        self.step_size = step
        self.speedup = speedup
        self.steps = 0
        self.clients = 0
        for endpoint in self.udp:
            sitl.attach(endpoint)

    def run(
        self,
        duration: float | None = None,
        should_stop: Callable[[], bool] | None = None,
    ) -> None:
        """Run for ``duration`` simulated seconds (None = until ``should_stop()`` or Ctrl-C)."""
        start_wall = time.monotonic()
        start_sim = self.sitl.time
        while duration is None or self.sitl.time - start_sim < duration - 1e-9:
            if should_stop is not None and should_stop():
                break
            for server in self.tcp:
                for client in server.accept():
                    self.sitl.attach(client)
                    self.clients += 1
            self.sitl.step(self.step_size)
            self.steps += 1
            due = start_wall + (self.sitl.time - start_sim) / self.speedup
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)

    def close(self) -> None:
        """Close the sockets and the simulator."""
        for endpoint in self.udp:
            endpoint.close()
        for server in self.tcp:
            server.close()
        self.sitl.close()
