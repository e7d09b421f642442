"""The live progress line of a lockstep flight on stderr.

A lockstep flight runs as fast as the CPU allows; a long one (a big world, a thousand
waypoints, hours of simulated time) would otherwise say nothing until it ends. On a terminal
the line is rewritten in place (``\\r``) a few times a second and cleared before each console
line and at the end; otherwise (a log file, CI) a plain line is printed every
``plain_every`` wall seconds, so short flights print none.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO


class FlightProgress:
    """Shows how far a lockstep flight is: simulated time of the limit, phase, behaviour."""

    def __init__(self, name: str, time_limit: float, waypoints: int,
                 stream: TextIO | None = None, plain_every: float = 30.0) -> None:
        self.name = name
        self.time_limit = time_limit
        self.waypoints = waypoints
        self.stream = stream if stream is not None else sys.stderr
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._every = 0.25 if self._tty else plain_every
        self._start = time.monotonic()
        self._next = self._start + self._every
        self._shown = False

    def due(self) -> bool:
        """Whether :meth:`show` would print now (cheap: call it every tick)."""
        return time.monotonic() >= self._next

    def line(self, sim_time: float, phase: str | None, behaviour: str | None) -> str:
        wall = time.monotonic() - self._start
        text = (f"flying {self.name}: {sim_time:.0f} of {self.time_limit:.0f} s simulated"
                f" ({100 * sim_time / self.time_limit:.0f} %)")
        if phase:
            text += f", {phase}"
        if behaviour:
            text += f" ({behaviour}{f' of {self.waypoints}' if 'Waypoint' in behaviour else ''})"
        if wall > 0:
            text += f", {sim_time / wall:.0f}x real time"
        return text + "; Ctrl-C stops and writes the report"

    def show(self, sim_time: float, phase: str | None, behaviour: str | None) -> None:
        self._next = time.monotonic() + self._every
        text = self.line(sim_time, phase, behaviour)
        if self._tty:
            self.stream.write("\r" + text[:200] + "\x1b[K")
            self._shown = True
        else:
            self.stream.write(text + "\n")
        self.stream.flush()

    def clear(self) -> None:
        """Take the in-place line away (before a console line, and at the end)."""
        if self._tty and self._shown:
            self.stream.write("\r\x1b[K")
            self.stream.flush()
            self._shown = False
