"""Clocks injected into everything that needs time (DESIGN.md section 3).

:class:`SimClock` is advanced by the lockstep runner, so simulated flights are deterministic
and run as fast as the CPU allows. :class:`VehicleClock` follows the vehicle's own time on a
live link (the ``time_boot_ms`` its messages carry), so a SITL run at any speed-up behaves as
at 1x in simulated time. :class:`WallClock` is plain monotonic wall time (diagnostics).
All satisfy :class:`behaviors.ports.Clock`.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable


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


class VehicleClock:
    """Seconds of the vehicle's own time since the clock was created, smoothed.

    The driver calls :meth:`observe` with the newest vehicle time stamp it decoded (seconds
    since the autopilot booted). The clock fits a line through the (wall, vehicle) samples of
    the last ``window`` wall seconds: its slope is :attr:`rate` (vehicle seconds per wall
    second, e.g. 8 against a SITL at 8x) and the clock slews towards the line over
    ``slew_time`` vehicle seconds, so jitter in when packets are read does not jerk it.

    It never goes backwards and never stops:

    * before the vehicle is heard it runs at wall speed (rate 1);
    * while the vehicle is silent it extrapolates at the last estimated rate;
    * a jump of more than ``resync`` vehicle seconds either way (a reboot resets
      ``time_boot_ms``; a paused simulator falls behind the extrapolation) re-anchors it: from
      there it follows the vehicle's time again, without stepping back.

    Thread-safe: the LSM worker thread stamps events with it too.

    Args:
        wall: the wall clock read (seconds, monotonic); injectable for tests.
        window: wall seconds of samples the rate is fitted over.
        slew_time: vehicle seconds over which an offset from the fitted line is absorbed.
        resync: vehicle seconds of disagreement beyond which the clock re-anchors.
    """

    def __init__(
        self,
        *,
        wall: Callable[[], float] = time.monotonic,
        window: float = 3.0,
        slew_time: float = 2.0,
        resync: float = 2.0,
    ) -> None:
        if not (window > 0 and slew_time > 0 and resync > 0):
            raise ValueError("window, slew_time and resync must be > 0")
        self._wall = wall
        self._window = float(window)
        self._slew_time = float(slew_time)
        self._resync = float(resync)
        self._lock = threading.Lock()
        self._w0 = wall()  # wall time of the anchor
        self._c0 = 0.0  # clock reading at the anchor
        self._rate = 1.0  # fitted vehicle seconds per wall second
        self._slew = 0.0  # extra clock seconds per wall second while absorbing an offset
        self._slew_end = self._w0  # wall time at which the slew is done
        self._offset: float | None = None  # clock - vehicle time (None until heard)
        self._samples: deque[tuple[float, float]] = deque()
        self._last = 0.0
        self.resyncs = 0  # re-anchors after a jump (reboot, pause)

    @property
    def rate(self) -> float:
        """Estimated vehicle seconds per wall second (1.0 until the vehicle is heard)."""
        return self._rate

    @property
    def heard(self) -> bool:
        """True once the vehicle's time has been observed."""
        return self._offset is not None

    def now(self) -> float:
        with self._lock:
            value = max(self._at(self._wall()), self._last)
            self._last = value
            return value

    def wall_seconds(self, seconds: float) -> float:
        """Wall seconds that ``seconds`` of this clock take at the current rate (pacing)."""
        return max(0.0, seconds) / self._rate

    def observe(self, vehicle_time: float, wall: float | None = None) -> None:
        """Feed the newest vehicle time stamp (s since boot), read at ``wall`` (default now)."""
        with self._lock:
            w = self._wall() if wall is None else float(wall)
            clock = max(self._at(w), self._last)
            if self._offset is None:
                self._restart(w, clock, vehicle_time)
                return
            if abs(vehicle_time + self._offset - clock) > self._resync:
                self.resyncs += 1
                # Never backwards: a vehicle ahead of us is caught up with at once, one behind
                # (rebooted, paused) is followed from here on.
                self._restart(w, max(clock, vehicle_time + self._offset), vehicle_time)
                return
            samples = self._samples
            if len(samples) > 1 and w - samples[-2][0] < self._window / 100:
                samples[-1] = (w, vehicle_time)  # keep the fit to ~100 points at any rate
            else:
                samples.append((w, vehicle_time))
            while len(samples) > 2 and w - samples[0][0] > self._window:
                samples.popleft()
            rate = self._fit(samples)
            if rate is not None:
                self._rate = rate
            # Where the fitted line says the clock should be now, and how far off it is.
            mean_w = sum(s[0] for s in samples) / len(samples)
            mean_v = sum(s[1] for s in samples) / len(samples)
            target = mean_v + self._rate * (w - mean_w) + self._offset
            error = target - clock
            slew_wall = self._slew_time / self._rate
            # At most half the rate either way, so the clock never stalls or races.
            slew = max(-0.5 * self._rate, min(0.5 * self._rate, error / slew_wall))
            self._w0, self._c0 = w, clock
            self._slew = slew
            self._slew_end = w + (abs(error / slew) if slew else 0.0)

    def _at(self, w: float) -> float:
        dt = w - self._w0
        slewing = max(0.0, min(dt, self._slew_end - self._w0))
        return self._c0 + self._rate * dt + self._slew * slewing

    def _restart(self, w: float, clock: float, vehicle_time: float) -> None:
        self._w0, self._c0 = w, clock
        self._slew, self._slew_end = 0.0, w
        self._offset = clock - vehicle_time
        self._samples.clear()
        self._samples.append((w, vehicle_time))
        self._last = max(self._last, clock)

    @staticmethod
    def _fit(samples: deque[tuple[float, float]]) -> float | None:
        """Least-squares slope of vehicle time over wall time, or None if too few samples."""
        n = len(samples)
        if n < 2:
            return None
        mean_w = sum(s[0] for s in samples) / n
        mean_v = sum(s[1] for s in samples) / n
        sww = sum((s[0] - mean_w) ** 2 for s in samples)
        if sww < 1e-6:  # all read within a millisecond: no slope to see yet
            return None
        slope = sum((s[0] - mean_w) * (s[1] - mean_v) for s in samples) / sww
        return slope if slope > 1e-3 else None
