"""The collision judge's terrain test: skipping the rotor disc's interpolation where the grid
cells around it are all below the rotors gives the contacts the full test gives."""

from __future__ import annotations

import numpy as np

from sitl.terrain.contact import ROTOR_HEIGHT, Contact, ContactJudge
from sitl.terrain.worlds import make_terrain


def _full_test(judge: ContactJudge, x: float, y: float, z: float) -> Contact | None:
    """The terrain contact from the heights of all 25 points of the disc."""
    ground = float(np.max(judge.terrain.height(x + judge._dx, y + judge._dy)))
    if z + ROTOR_HEIGHT <= judge._highest and ground > z + ROTOR_HEIGHT:
        return Contact(0.0, (x, y, z), "terrain", None, ground - z)
    return None


def test_the_terrain_contact_is_the_full_tests_everywhere():
    terrain = make_terrain({"kind": "mars", "size": [60.0, 60.0], "cell_size": 0.2}, seed=3)
    judge = ContactJudge(terrain)
    rng = np.random.default_rng(0)
    # Over and off the grid (its edges continue outward), from the ground up to above the
    # rotors' reach, most within the last metre where the two tests part.
    x = rng.uniform(-40.0, 40.0, 3000)
    y = rng.uniform(-40.0, 40.0, 3000)
    ground = terrain.height(x, y)
    z = ground + np.concatenate([rng.uniform(-0.6, 0.6, 2000), rng.uniform(-2.0, 3.0, 1000)])
    contacts = 0
    for xi, yi, zi in zip(x.tolist(), y.tolist(), z.tolist(), strict=True):
        got = judge.contact((xi, yi, zi), 0.0)
        assert got == _full_test(judge, xi, yi, zi)
        contacts += got is not None
    assert 100 < contacts < 2900  # both verdicts well represented
