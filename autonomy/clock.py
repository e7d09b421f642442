"""Clocks injected into everything that needs time (DESIGN.md section 3).

:class:`SimClock` is advanced by the lockstep runner, so simulated flights are deterministic
and run as fast as the CPU allows; :class:`WallClock` is monotonic wall time for live links.
Both satisfy :class:`behaviors.ports.Clock`.
"""

from __future__ import annotations

import time


class SimClock:
    """Simulated time in seconds, advanced explicitly."""

    def __init__(self, start: float = 0.0) -> None:
        self._now = float(start)

    def now(self) -> float:
        return self._now

    def advance(self, dt: float) -> float:
        if dt < 0:
            raise ValueError(f"cannot advance a clock by a negative step ({dt} s)")
        self._now += dt
        return self._now


class WallClock:
    """Monotonic wall time in seconds since the clock was created."""

    def __init__(self) -> None:
        self._t0 = time.monotonic()

    def now(self) -> float:
        return time.monotonic() - self._t0
