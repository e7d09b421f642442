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


def test_small_batches_are_validated_as_large_ones(monkeypatch):
    """The row-by-row checks of a small batch reject exactly what the vectorised ones do, for
    the same reason: non-finite values, out-of-range fields, ban zones (their edge
    included) and the distance from the drone (its edge included)."""
    from lsm import SiteObservation
    from lsm import manager as module

    manager = LandingSiteManager(LsmSettings(max_distance=300.0, ban_radius=5.0), LossWeights())
    manager.set_drone_position((10.0, -20.0, 30.0))
    for x, y in ((40.0, 40.0), (-60.0, 10.0)):
        manager.submit(SiteObservation(x, y, 0.0, 0.1, 0.1, 3.0, 0.0, 20.0))
    manager.process_pending()
    for site in list(manager.ranked()):
        assert manager.ban(site.id)
    rng = np.random.default_rng(8)
    picks = [np.nan, np.inf, -np.inf, -0.5, 0.0, 1.0, 1.5, 2e7, -2e7]
    batch = []
    for _ in range(400):
        v = [float(rng.uniform(-400, 400)), float(rng.uniform(-400, 400)),
             float(rng.uniform(-5, 5)), float(rng.uniform(0, 1)), float(rng.uniform(0, 1)),
             float(rng.uniform(0, 10)), 3.0, float(rng.uniform(0, 50)), 1.0]
        if rng.random() < 0.5:
            v[int(rng.integers(0, 9))] = float(picks[int(rng.integers(len(picks)))])
        if rng.random() < 0.1:  # on a ban zone's edge, or at max_distance from the drone
            angle = float(rng.uniform(0, 2 * np.pi))
            centre, radius = ((40.0, 40.0), 5.0) if rng.random() < 0.5 else ((10.0, -20.0), 300.0)
            v[0], v[1] = centre[0] + radius * np.cos(angle), centre[1] + radius * np.sin(angle)
        batch.append(SiteObservation(*v))
    small = [manager._validate(batch[i : i + 8]) for i in range(0, len(batch), 8)]
    monkeypatch.setattr(module, "_SMALL_BATCH", 0)
    large = [manager._validate(batch[i : i + 8]) for i in range(0, len(batch), 8)]
    for (vals_s, reasons_s), (vals_l, reasons_l) in zip(small, large, strict=True):
        assert reasons_s == reasons_l
        np.testing.assert_array_equal(vals_s, vals_l)
    found = {r for _, reasons in small for r in reasons}
    assert {None, "non_finite", "position_out_of_range", "roughness_out_of_range",
            "uncertainty_out_of_range", "negative_size", "negative_observation_altitude",
            "banned_zone", "beyond_max_distance"} <= found


def test_small_and_large_batches_count_redetections_alike(monkeypatch):
    """Redetections bump the detection count and last-seen time of their site the same way
    row by row (a few) as with numpy's ufunc.at (many), several of one site in a batch and
    late or early timestamps included."""
    from lsm import SiteObservation
    from lsm import manager as module

    def run() -> list[tuple[int, int, float]]:
        manager = LandingSiteManager(LsmSettings(match_radius=2.0), LossWeights())
        manager.set_drone_position((0.0, 0.0, 30.0))
        rng = np.random.default_rng(9)
        centres = rng.uniform(-100, 100, (12, 2))
        for x, y in centres:
            manager.submit(SiteObservation(float(x), float(y), 0.0, 0.2, 0.2, 2.0, 0.0, 30.0, 0.0))
        manager.process_pending()
        for step in range(40):
            for _ in range(int(rng.integers(1, 6))):
                x, y = centres[int(rng.integers(len(centres)))]
                t = float(step + rng.uniform(-3.0, 1.0))
                manager.submit(SiteObservation(float(x) + 0.1, float(y), 0.0, 0.2, 0.2, 2.0,
                                               0.0, 40.0, t))
            manager.process_pending()
        return sorted((s.id, s.detection_count, s.last_seen) for s in manager.ranked())

    small = run()
    monkeypatch.setattr(module, "_SMALL_BATCH", 0)
    assert run() == small
    assert max(count for _, count, _ in small) > 5


def test_few_sites_match_as_with_the_tree(monkeypatch):
    """With few sites every snapshot entry is a candidate instead of the k-d tree's nearest:
    the same decisions (inserted, merged, updated, replaced, dropped) and the same sites,
    over a stream of redetections that move sites, new sites, bans and drone moves."""
    from lsm import SiteObservation
    from lsm import manager as module

    def run() -> tuple[list, list]:
        decisions = []
        m = LandingSiteManager(LsmSettings(capacity=8, match_radius=2.0, ban_radius=2.5),
                               LossWeights(), on_decision=lambda d: decisions.append(
                                   (d.kind, d.site_id, d.reason)))
        rng = np.random.default_rng(11)
        centres = rng.uniform(-12, 12, (14, 2))
        for step in range(150):
            m.set_drone_position((float(rng.uniform(-5, 5)), float(rng.uniform(-5, 5)), 20.0))
            for _ in range(int(rng.integers(1, 5))):
                cx, cy = centres[int(rng.integers(len(centres)))]
                x, y = rng.normal((cx, cy), 1.2)
                m.submit(SiteObservation(float(x), float(y), 0.0, float(rng.uniform(0, 1)),
                                         0.2, float(rng.uniform(0.5, 5)), 0.0,
                                         float(rng.uniform(2, 40)), float(step)))
            m.process_pending()
            if step % 37 == 36 and len(m):
                m.ban(m.best().id)
        return decisions, list(m.ranked())

    few = run()
    monkeypatch.setattr(module, "_FEW_SITES", -1)
    tree = run()
    assert few == tree
    kinds = {kind for kind, _, _ in few[0]}
    assert {"inserted", "merged", "updated", "replaced"} <= kinds
