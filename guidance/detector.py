"""The laser detector of seed 004 (section 4.1.1): lit light sensors -> bearing of the light.

Twelve sensors on a ring, 30 deg each, sensor i centred i * 30 deg clockwise from the nose.
A lit sensor stands for its whole sector; when several are lit (neighbours at range, a
momentary reflection) their sectors are "added up and the middle value returned": the middle
of the shortest arc of the ring that covers every lit sector (the complement of the widest
run of dark sensors).
"""

from __future__ import annotations

import math

import numpy as np


def ring_bearing(mask: int, sensors: int = 12) -> float | None:
    """Bearing of the light, radians clockwise from the nose in [0, 2 pi), from the bit mask
    of lit ring sensors (bit i = sensor i; higher bits are ignored), or None when no sensor
    or every sensor is lit (no direction to tell)."""
    bits = (int(mask) >> np.arange(sensors)) & 1
    lit = np.flatnonzero(bits)
    if lit.size == 0 or lit.size == sensors:
        return None
    # Gap (in sectors) from each lit sensor to the next lit one, clockwise.
    gaps = (np.roll(lit, -1) - lit) % sensors
    gaps[gaps == 0] = sensors  # a single lit sensor: the gap is the whole ring
    widest = int(np.argmax(gaps))
    start = lit[(widest + 1) % lit.size]  # the covering arc starts after the widest gap ...
    end = lit[widest]  # ... and ends where that gap begins
    span = (end - start) % sensors
    middle = (start + 0.5 * span) % sensors
    return float(middle * 2.0 * math.pi / sensors)
