"""Small batches take a per-row path (Python floats) where large ones are vectorised: both
give every observation the same spatial-hash key, cell boundaries and NaN rows included."""

from __future__ import annotations

import numpy as np

from lsm import LandingSiteManager, LossWeights, LsmSettings
from lsm.manager import _SMALL_BATCH


def test_small_and_large_batches_hash_observations_alike():
    manager = LandingSiteManager(LsmSettings(match_radius=1.5), LossWeights())
    rng = np.random.default_rng(3)
    n = 40 * _SMALL_BATCH
    xy = rng.uniform(-5000, 5000, (n, 2))
    cell = manager._cell_size
    xy[::3] = np.round(xy[::3] / cell) * cell + 1.5  # on the boundaries of the match keys
    xy[::7] = -xy[::7]
    vals = np.zeros((n, 9))
    vals[:, :2] = xy
    vals[5, 0] = np.nan  # rejected rows: any key will do, but no error
    vals[6, 1] = np.inf
    whole = manager._match_keys(vals)
    pieces = [key for start in range(0, n, _SMALL_BATCH)
              for key in manager._match_keys(vals[start : start + _SMALL_BATCH])]
    keep = np.isfinite(vals[:, :2]).all(axis=1)
    assert [k for k, ok in zip(whole, keep, strict=True) if ok] == [
        k for k, ok in zip(pieces, keep, strict=True) if ok]
    assert len(pieces) == n
