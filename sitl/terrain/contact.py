"""Ground truth of what the vehicle touches besides its landing: collisions with raised
terrain (a wall, a tree, a rock) and with moving obstacles, and touchdowns too close to a
moving obstacle.

The vehicle is a disc of the footprint radius (its rotors) ``ROTOR_HEIGHT`` above its skids
(the position the simulator flies). It collides with the terrain when ground within that
disc rises above the rotors, and with a moving obstacle when the obstacle's footprint comes
within the disc while the vehicle is below the obstacle's top (or rests on it: the
simulator sets a landing vehicle down on a car's roof). ``ROTOR_HEIGHT`` is above
what safe ground (:mod:`sitl.terrain.safety`: slope <= 15 deg, deviations <= 0.1 m) can
rise within the 1 m footprint (tan 15 deg x 1 m + 0.1 m = 0.37 m), so a touchdown judged
safe is never a collision.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sitl.terrain.grid import Terrain
from sitl.terrain.moving import KINDS
from sitl.terrain.safety import SafetySettings

ROTOR_HEIGHT = 0.4
"""m: the rotor disc above the skids."""

RESTING = 0.05
"""m: skids this close above an obstacle's top touch it (the simulator sets the vehicle down
on a car's roof: that is a collision, not a landing)."""


@dataclass(frozen=True)
class Contact:
    """The vehicle touching something at one instant.

    Attributes:
        time: simulated seconds.
        position: (x, y, z) of the vehicle (its skids), ENU m.
        obstacle: ``"terrain"``, ``"person"`` or ``"vehicle"``.
        index: the moving obstacle's index (None for the terrain).
        height: m the obstacle (or ground) stands above the vehicle's skids there.
    """

    time: float
    position: tuple[float, float, float]
    obstacle: str
    index: int | None
    height: float

    def as_dict(self) -> dict:
        return {"t": round(self.time, 3), "obstacle": self.obstacle, "index": self.index,
                "position": [round(v, 3) for v in self.position],
                "height": round(self.height, 3)}


class ContactJudge:
    """Collisions of the vehicle with a world (see the module's docstring).

    Args:
        terrain: the world (its ``moving`` obstacles included).
        settings: the footprint (its radius is the rotor disc's) and clearance.
    """

    def __init__(self, terrain: Terrain, settings: SafetySettings | None = None) -> None:
        self.terrain = terrain
        self.settings = s = settings or SafetySettings()
        r = s.footprint_radius
        # the rotor disc: its centre and rings at half and full radius
        a8 = np.linspace(0, 2 * np.pi, 8, endpoint=False)
        a16 = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        self._dx = np.concatenate([[0.0], 0.5 * r * np.cos(a8), r * np.cos(a16)])
        self._dy = np.concatenate([[0.0], 0.5 * r * np.sin(a8), r * np.sin(a16)])
        self._highest = float(terrain.grid.max())
        moving = terrain.moving
        self._tallest = 0.0 if moving is None or len(moving) == 0 else float(
            moving.height.max())

    def contact(self, position, t: float) -> Contact | None:
        """What the vehicle at ``position`` (ENU, its skids) touches at time ``t`` (s): the
        first moving obstacle, else the terrain, else None."""
        x, y, z = (float(v) for v in position)
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            return None
        if z - ROTOR_HEIGHT > self._highest + self._tallest:
            return None  # above everything there is (the cruise): nothing to test
        r = self.settings.footprint_radius
        moving = self.terrain.moving
        if moving is not None and len(moving) and moving.near(x, y, r):
            snap = moving.at(t)
            touching = (snap.footprint_distance(x, y) < r) & (z < snap.top + RESTING) & (
                z + ROTOR_HEIGHT > snap.base)
            if touching.any():
                k = int(np.flatnonzero(touching)[0])
                return Contact(float(t), (x, y, z), KINDS[int(snap.kind[k])], k,
                               float(snap.top[k] - z))
        rotors = z + ROTOR_HEIGHT
        if rotors <= self._highest and not self._clear_below(x, y, rotors):
            ground = float(np.max(self.terrain.height(x + self._dx, y + self._dy)))
            if ground > rotors:
                return Contact(float(t), (x, y, z), "terrain", None, ground - z)
        return None

    def _clear_below(self, x: float, y: float, rotors: float) -> bool:
        """Whether no ground under the rotor disc at (x, y) can reach ``rotors`` (ENU z, m),
        judged from the grid cells around the disc: each height the disc's points are given
        (:meth:`Terrain.height`, bilinear between the four cells around a point) lies
        between those cells' heights, up to rounding, which the 1 cm kept below ``rotors``
        covers. A few microseconds instead of interpolating the 25 points, which then only
        the last centimetres above the ground (and the ground itself) need."""
        terrain = self.terrain
        ny, nx = terrain.grid.shape
        reach = self.settings.footprint_radius / terrain.cell_size + 1.0  # cells, one spare
        fx = (x - terrain.origin[0]) / terrain.cell_size
        fy = (y - terrain.origin[1]) / terrain.cell_size
        # The cells a point's interpolation may read: columns j and j + 1, where j is its
        # column clipped to 0 .. nx - 2 (the same for rows).
        j0 = min(max(math.floor(fx - reach), 0), nx - 2)
        j1 = min(max(math.floor(fx + reach) + 2, 2), nx)
        i0 = min(max(math.floor(fy - reach), 0), ny - 2)
        i1 = min(max(math.floor(fy + reach) + 2, 2), ny)
        return float(terrain.grid[i0:i1, j0:j1].max()) < rotors - 0.01


def clear_of_moving(terrain: Terrain, x: float, y: float, t: float,
                    settings: SafetySettings | None = None) -> bool:
    """No moving obstacle's footprint is within the clearance disk (footprint radius +
    clearance margin) of a touchdown at (x, y) at time ``t``: the moving half of the
    touchdown's ground truth (:func:`sitl.terrain.safety.is_safe` is the static half)."""
    moving = terrain.moving
    if moving is None or len(moving) == 0:
        return True
    s = settings or SafetySettings()
    distance = moving.at(t).footprint_distance(float(x), float(y))
    return bool(np.all(distance > s.footprint_radius + s.clearance_margin))
