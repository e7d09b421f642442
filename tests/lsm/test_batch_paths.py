"""The batch paths of the manager against straightforward ones: validation against row-by-row
checks, redetection counts row by row against numpy's ufunc.at, and the redetection lookup
(one distance matrix per batch over the snapshot) against a k-d tree query per row."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lsm import LandingSiteManager, LossWeights, LsmSettings

FIELDS = ("x", "y", "z", "roughness", "uncertainty", "size", "obstacle_altitude",
          "observation_altitude", "timestamp")
MAX_COORDINATE = 1e7  # m, the manager's bound on |x|, |y|, |z|


def test_large_batches_key_observations_as_rows_alone():
    """A large batch keys its rows for the spatial hash with numpy, a small one row by row
    in Python floats: the same key for every observation, cell boundaries included."""
    manager = LandingSiteManager(LsmSettings(match_radius=1.5), LossWeights())
    rng = np.random.default_rng(3)
    n = 1280
    xy = rng.uniform(-5000, 5000, (n, 2))
    cell = manager._cell_size
    xy[::3] = np.round(xy[::3] / cell) * cell + 1.5  # on the boundaries of the match keys
    xy[::7] = -xy[::7]
    vals = np.zeros((n, 9))
    vals[:, :2] = xy
    r = 1.5
    by_row = [math.floor((x - r) / cell) * 2**32 + math.floor((y - r) / cell)
              for x, y in xy.tolist()]
    assert manager._match_keys(vals) == by_row
    vals[5, 0] = np.nan  # rejected rows: any key will do, but no error
    vals[6, 1] = np.inf
    assert len(manager._match_keys(vals)) == n


def row_reasons(rows, bans, drone, limit):
    """DESIGN.md's rejection rules, row by row in plain floats, first broken rule named."""
    reasons = []
    for row in rows:
        x, y, z, rough, unc, size, _, obs_alt, _ = row
        if not all(math.isfinite(v) for v in row):
            reasons.append("non_finite")
        elif max(abs(x), abs(y), abs(z)) > MAX_COORDINATE:
            reasons.append("position_out_of_range")
        elif not 0 <= rough <= 1:
            reasons.append("roughness_out_of_range")
        elif not 0 <= unc <= 1:
            reasons.append("uncertainty_out_of_range")
        elif size < 0:
            reasons.append("negative_size")
        elif obs_alt < 0:
            reasons.append("negative_observation_altitude")
        elif any((x - bx) * (x - bx) + (y - by) * (y - by) <= r * r for bx, by, r in bans):
            reasons.append("banned_zone")
        elif math.sqrt((x - drone[0]) * (x - drone[0]) + (y - drone[1]) * (y - drone[1])) > limit:
            reasons.append("beyond_max_distance")
        else:
            reasons.append(None)
    return reasons


@pytest.mark.filterwarnings("ignore:overflow encountered")  # 1e308 squared: rejected anyway
def test_batches_are_validated_as_row_by_row():
    """A batch's checks (all rows within every bound at once, else rule by rule) reject
    exactly what row-by-row checks do, for the same reason, in batches and alone:
    non-finite values, out-of-range fields, ban zones (their edge included) and the
    distance from the drone (its edge included)."""
    from lsm import SiteObservation

    manager = LandingSiteManager(LsmSettings(max_distance=300.0, ban_radius=5.0), LossWeights())
    manager.set_drone_position((10.0, -20.0, 30.0))
    for x, y in ((40.0, 40.0), (-60.0, 10.0)):
        manager.submit(SiteObservation(x, y, 0.0, 0.1, 0.1, 3.0, 0.0, 20.0))
    manager.process_pending()
    for site in list(manager.ranked()):
        assert manager.ban(site.id)
    rng = np.random.default_rng(8)
    picks = [np.nan, np.inf, -np.inf, -0.5, -0.0, 0.0, 1.0, 1.5, 1e7, 2e7, -2e7, 1e308]
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
    bans = [tuple(zone) for zone in manager.ban_zones()]
    expected = row_reasons([[getattr(o, f) for f in FIELDS] for o in batch], bans,
                           (10.0, -20.0), 300.0)
    for size in (1, 8, 400):
        reasons = []
        for i in range(0, len(batch), size):
            vals, part = manager._validate(batch[i : i + size])
            reasons += part
            np.testing.assert_array_equal(
                vals, [[getattr(o, f) for f in FIELDS] for o in batch[i : i + size]])
        assert reasons == expected
    assert set(expected) == {None, "non_finite", "position_out_of_range", "roughness_out_of_range",
                             "uncertainty_out_of_range", "negative_size",
                             "negative_observation_altitude", "banned_zone",
                             "beyond_max_distance"}


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


def lookup_run(seed: int) -> tuple[list, list, dict]:
    """A stream that makes the lookup's hard cases frequent: sites on a metre grid (so
    several lie at exactly the same distance from an observation, as the detector's grid
    cells do), updates that move sites, evictions at capacity, bans, drone moves, batches of
    1 to 60 observations. Returns the decisions, the final sites and the counters."""
    from lsm import SiteObservation

    decisions = []
    m = LandingSiteManager(
        LsmSettings(capacity=40, match_radius=3.0, ban_radius=2.0, max_distance=20.0),
        LossWeights(), on_decision=lambda d: decisions.append(
            (d.kind, d.site_id, d.reason, d.timestamp)))
    rng = np.random.default_rng(seed)
    t = 0.0
    for step in range(120):
        if step % 10 == 0:
            m.set_drone_position((float(rng.uniform(-15, 15)), float(rng.uniform(-15, 15)), 30.0))
        for _ in range(int(rng.integers(1, 61))):
            t += 0.1
            x, y = rng.integers(-12, 13, 2) + 0.5
            m.submit(SiteObservation(float(x), float(y), 0.0, float(rng.uniform(0, 1)),
                                     float(rng.uniform(0, 1)), float(rng.uniform(0.5, 5)),
                                     0.0, float(rng.uniform(2, 100 - 0.8 * step)), t))
        m.process_pending()
        if step % 25 == 24 and len(m):
            m.ban(m.ranked()[int(rng.integers(len(m)))].id)
    return decisions, list(m.ranked()), m.counters()


@pytest.mark.parametrize("seed", [1, 2])
def test_distance_matrix_lookup_matches_the_tree_query(monkeypatch, seed):
    """The redetection lookup by one distance matrix per batch over the snapshot (small
    stores) decides every observation as the k-d tree query per row does (large stores):
    the same decisions in the same order, the same sites with the same values, the same
    counters, on a stream full of exactly equidistant sites; also with stores switching
    between the two paths, and with every snapshot queried rather than examined whole."""
    from lsm import manager as module

    queried = []
    tree_candidates = module.LandingSiteManager._tree_candidates

    def counted(self, vals, rows):
        queried.append(len(rows))
        return tree_candidates(self, vals, rows)

    monkeypatch.setattr(module.LandingSiteManager, "_tree_candidates", counted)
    matrix = lookup_run(seed)
    tied_rows = sum(queried)
    assert tied_rows > 0  # the stream has rows whose nearest entries tie
    monkeypatch.setattr(module, "_BRUTE_SITES", -1)
    assert lookup_run(seed) == matrix
    for brute, few in ((20, 8), (1000, -1)):
        monkeypatch.setattr(module, "_BRUTE_SITES", brute)
        monkeypatch.setattr(module, "_FEW_SITES", few)
        assert lookup_run(seed) == matrix
    kinds = {kind for kind, *_ in matrix[0]}
    assert {"inserted", "merged", "updated", "replaced", "dropped", "banned"} <= kinds
