"""LiPo battery: coulomb counting with a draw that grows with climb rate and speed."""

from __future__ import annotations

from .settings import BatterySettings

_CELL_FULL = 4.2  # V
_CELL_EMPTY = 3.5  # V
_CELL_SAG = 0.004  # V per A per cell (internal resistance)


class Battery:
    """Remaining charge of one pack. ``drain`` is called once per physics step."""

    def __init__(self, settings: BatterySettings) -> None:
        self.settings = settings
        self.consumed_mah = 0.0
        self.energy_j = 0.0
        self.current = settings.idle_current

    @property
    def remaining(self) -> float:
        """Fraction of capacity left, 0..1."""
        return max(0.0, 1.0 - self.consumed_mah / self.settings.capacity_mah)

    @property
    def percent(self) -> float:
        return 100.0 * self.remaining

    @property
    def voltage(self) -> float:
        """Terminal voltage, V: linear in the charge left, sagging under load."""
        s = self.settings
        cell = _CELL_EMPTY + (_CELL_FULL - _CELL_EMPTY) * self.remaining - _CELL_SAG * self.current
        return s.cells * cell

    @property
    def empty(self) -> bool:
        return self.consumed_mah >= self.settings.capacity_mah

    def drain(self, dt: float, *, flying: bool, climb_rate: float, speed: float) -> None:
        """Draw current for ``dt`` seconds; climb_rate (m/s, up > 0) and speed (m/s)."""
        s = self.settings
        if flying:
            current = s.hover_current + s.climb_current * max(climb_rate, 0.0)
            current += s.speed_current * speed
        else:
            current = s.idle_current
        self.current = current
        self.consumed_mah += current * dt / 3.6
        # Energy at the nominal voltage: close enough, and cheap (this runs every step).
        self.energy_j += current * s.cells * 3.7 * dt
