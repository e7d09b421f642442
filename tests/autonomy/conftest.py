"""An embedded SITL served over TCP in real time (faster than real time), for live flights:
the vehicle a live ``lander fly`` meets, which the test can pause, resume or kill."""

from __future__ import annotations

import threading

import pytest

from sitl import Sitl, SitlSettings
from sitl.copter import HomeSettings
from sitl.realtime import RealTimeRunner
from sitl.transports import TcpServer


class ServedSitl:
    """A :class:`sitl.Sitl` stepped by a RealTimeRunner on its own thread, on TCP."""

    def __init__(self, speedup: float, home: HomeSettings | None = None,
                 settings: SitlSettings | None = None) -> None:
        settings = settings or SitlSettings()
        if home is not None:
            settings = settings.model_copy(update={"home": home})
        self.sitl = Sitl(settings, autopilot="ardupilot")
        self.server = TcpServer("127.0.0.1", 0)
        self.runner = RealTimeRunner(self.sitl, tcp=[self.server], speedup=speedup)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.closed = False
        self.resume()

    @property
    def url(self) -> str:
        return f"tcp:127.0.0.1:{self.server.address[1]}"

    def resume(self) -> None:
        """Step the simulator again (from where it stopped: no catching up)."""
        self._stop.clear()
        self._thread = threading.Thread(
            target=self.runner.run, kwargs={"should_stop": self._stop.is_set}, daemon=True
        )
        self._thread.start()

    def pause(self) -> None:
        """Stop stepping: the vehicle falls silent, its sockets stay open."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=10)

    def kill(self) -> None:
        """The autopilot dies: stop stepping and close every socket."""
        self.pause()
        if not self.closed:
            self.closed = True
            self.runner.close()


@pytest.fixture
def served_sitl():
    """served_sitl(speedup, home=None, settings=None) -> ServedSitl; killed after the test."""
    made: list[ServedSitl] = []

    def factory(speedup: float, home: HomeSettings | None = None,
                settings: SitlSettings | None = None) -> ServedSitl:
        served = ServedSitl(speedup, home, settings)
        made.append(served)
        return served

    yield factory
    for served in made:
        served.kill()
