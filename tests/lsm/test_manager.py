"""Rules of the Landing Site Manager (DESIGN.md section 4), through its public API."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from lsm import (
    LandingSiteManager,
    LossWeights,
    LsmSettings,
    SiteObservation,
    site_loss,
)


def obs(x=0.0, y=0.0, *, z=0.0, rough=0.1, unc=0.1, size=3.0, obst=1.0, alt=100.0, t=0.0,
        source="sfm"):
    return SiteObservation(x, y, z, rough, unc, size, obst, alt, t, source)


def manager(**settings):
    return LandingSiteManager(LsmSettings(**settings), LossWeights())


def feed(m, *observations):
    for o in observations:
        m.submit(o)
    m.process_pending()


def test_loss_follows_eq_3_1():
    w = LossWeights(dist=2.0, rough=3.0, var=4.0, size=5.0, ver_alt=6.0, normaliser=50.0)
    loss = site_loss(np.array([25.0]), np.array([0.2]), np.array([0.5]), np.array([2.0]),
                     np.array([10.0]), 4.0, w)
    expected = 2.0 * 25 / 50 + 3.0 * 0.2 + 4.0 * 0.5 - 5.0 * 2.0 / 4.0 + 6.0 * 10 / 50
    assert loss[0] == pytest.approx(expected)


def test_ranked_is_ascending_in_loss_at_the_drone_position():
    m = manager()
    feed(m, obs(0, 0), obs(40, 0), obs(80, 0))
    ranking = m.ranked((80, 0, 100))
    assert [s.x for s in ranking] == [80, 40, 0]
    assert list(ranking.losses) == sorted(ranking.losses)
    assert m.best((0, 0, 100)).x == 0


def test_loss_in_ranking_uses_distance_roughness_uncertainty_size_and_ver_alt():
    m = manager()
    feed(m, obs(10, 0, rough=0.2, unc=0.3, size=2.0, alt=50.0), obs(-20, 0, size=4.0))
    site = next(s for s in m.ranked((0, 0, 100)) if s.x == 10)
    w = LossWeights()
    expected = 10 / 100 + 0.2 + 0.3 - 2.0 / 4.0 + 50 / 100
    assert site.loss == pytest.approx(expected)
    assert site.loss == pytest.approx(w.dist * 0.1 + 0.2 + 0.3 - 0.5 + 0.5)


def test_redetection_from_lower_altitude_takes_the_new_properties():
    m = manager()
    feed(m, obs(5, 5, rough=0.5, unc=0.6, size=2.0, alt=100.0, t=1.0))
    feed(m, obs(5.5, 5.0, rough=0.05, unc=0.02, size=4.0, alt=2.5, t=9.0, source="stereo"))
    [site] = m.ranked()
    assert (site.x, site.roughness, site.uncertainty, site.size) == (5.5, 0.05, 0.02, 4.0)
    assert site.verification_altitude == 2.5
    assert site.detection_count == 2
    assert (site.first_seen, site.last_seen) == (1.0, 9.0)
    assert site.source == "stereo"
    assert m.is_verified(site)
    assert m.counters()["updated"] == 1


def test_redetection_from_higher_altitude_keeps_the_old_properties():
    m = manager()
    feed(m, obs(5, 5, rough=0.05, size=4.0, alt=3.0, t=1.0))
    feed(m, obs(5.5, 5, rough=0.9, size=1.0, alt=80.0, t=2.0))
    [site] = m.ranked()
    assert (site.x, site.roughness, site.size, site.verification_altitude) == (5, 0.05, 4.0, 3.0)
    assert site.detection_count == 2
    assert site.last_seen == 2.0
    assert m.counters()["merged"] == 2 - 1 and m.counters()["updated"] == 0


def test_observation_outside_match_radius_is_a_new_site():
    m = manager(match_radius=2.0)
    feed(m, obs(0, 0), obs(2.5, 0))
    assert len(m) == 2


def test_worst_site_is_evicted_when_a_better_one_arrives_at_capacity():
    m = manager(capacity=3)
    feed(m, obs(0, 0, rough=0.1), obs(10, 0, rough=0.9), obs(20, 0, rough=0.2))
    worst_id = max(m.ranked((0, 0, 100)), key=lambda s: s.loss).id
    feed(m, obs(30, 0, rough=0.0, unc=0.0))
    assert len(m) == 3
    assert m.get(worst_id) is None
    assert m.counters()["replaced"] == 1


def test_a_site_worse_than_all_is_rejected_at_capacity():
    m = manager(capacity=2)
    feed(m, obs(0, 0, rough=0.1), obs(10, 0, rough=0.1))
    before = {s.id for s in m.ranked()}
    feed(m, obs(20, 0, rough=1.0, unc=1.0, size=0.5))
    assert {s.id for s in m.ranked()} == before
    assert m.counters()["rejected_worse_than_worst"] == 1


def test_sites_beyond_max_distance_fall_off():
    m = manager(max_distance=50.0)
    m.set_drone_position((0, 0, 100))
    feed(m, obs(10, 0), obs(40, 0))
    m.set_drone_position((-30, 0, 100))
    assert [s.x for s in m.ranked()] == [10]
    assert m.counters()["dropped"] == 1
    feed(m, obs(60, 0))
    assert m.counters()["rejected_beyond_max_distance"] == 1


def test_banned_site_neighbourhood_rejects_new_observations():
    m = manager(ban_radius=3.0)
    feed(m, obs(0, 0), obs(20, 0))
    site = next(s for s in m.ranked() if s.x == 0)
    assert m.ban(site.id)
    assert m.get(site.id) is None
    feed(m, obs(1.0, 1.0), obs(2.9, 0), obs(3.5, 0))
    assert [s.x for s in m.ranked((0, 0, 0))] == [3.5, 20]
    c = m.counters()
    assert c["banned"] == 1 and c["banned_rejected"] == 2 and c["rejected_banned_zone"] == 2
    assert m.ban_zones() == [(0.0, 0.0, 3.0)]
    assert not m.ban(site.id)


@pytest.mark.parametrize(
    ("bad", "reason"),
    [
        (obs(math.nan, 0), "non_finite"),
        (obs(0, math.inf), "non_finite"),
        (obs(0, 0, z=math.nan), "non_finite"),
        (obs(0, 0, size=math.inf), "non_finite"),
        (obs(0, 0, t=math.nan), "non_finite"),
        (obs(0, 0, rough=1.5), "roughness_out_of_range"),
        (obs(0, 0, rough=-0.1), "roughness_out_of_range"),
        (obs(0, 0, unc=2.0), "uncertainty_out_of_range"),
        (obs(0, 0, size=-1.0), "negative_size"),
        (obs(0, 0, alt=-3.0), "negative_observation_altitude"),
        ("not an observation", "malformed"),
        (SiteObservation("a", 0, 0, 0, 0, 1, 0, 1), "malformed"),
    ],
)
def test_bad_observations_are_rejected_and_counted_never_stored(bad, reason):
    m = manager()
    m.submit(bad)  # never raises into the producer
    feed(m, obs(50, 50))
    assert len(m) == 1
    c = m.counters()
    assert c[f"rejected_{reason}"] == 1
    assert c["received"] == c["inserted"] + c["merged"] + c["rejected"] == 2


def test_verified_means_verification_altitude_within_tolerance():
    m = manager(verification_altitude=2.5, verification_tolerance=0.5)
    feed(m, obs(0, 0, alt=3.0), obs(10, 0, alt=3.2))
    by_x = {s.x: s for s in m.ranked()}
    assert m.is_verified(by_x[0])
    assert not m.is_verified(by_x[10])


def test_best_verified_is_the_lowest_loss_site_seen_from_the_verification_altitude():
    m = manager(verification_altitude=2.5, verification_tolerance=0.5)
    feed(m, obs(0, 0, rough=0.0, alt=40.0), obs(10, 0, rough=0.6, alt=2.6),
         obs(20, 0, rough=0.3, alt=2.9), obs(30, 0, rough=0.1, alt=3.1))
    assert m.best((0, 0, 10)).x == 0  # the best site overall is not verified
    assert m.best_verified((0, 0, 10)).x == 20  # of the verified two, the lower loss
    m.ban(m.best_verified().id)
    assert m.best_verified().x == 10
    m.ban(m.best_verified().id)
    assert m.best_verified() is None  # 3.1 m is beyond 2.5 + 0.5
    assert len(m.ranked()) == 2


def test_snapshot_is_a_copy():
    m = manager()
    feed(m, obs(0, 0))
    snap = m.snapshot()
    feed(m, obs(30, 0))
    assert len(snap.sites) == 1 and snap.counters["inserted"] == 1
    assert len(m.snapshot().sites) == 2


def test_decisions_are_reported():
    seen = []
    m = LandingSiteManager(LsmSettings(capacity=1), on_decision=seen.append)
    feed(m, obs(0, 0, t=1.0), obs(0.5, 0, alt=2.0, t=2.0), obs(50, 0, rough=0.0, unc=0.0,
                                                              alt=1.0, t=3.0))
    m.ban(m.best().id)
    assert [d.kind for d in seen] == ["inserted", "updated", "replaced", "inserted", "banned"]
    assert seen[1].timestamp == 2.0


def test_worker_thread_drains_the_queue_and_stop_loses_nothing():
    m = manager(capacity=1000)
    with m:
        for i in range(2000):
            m.submit(obs(float(i % 500) * 5, 0.0, t=float(i)))
    c = m.counters()
    assert c["received"] == 2000
    assert c["inserted"] == 500 and c["merged"] == 1500


@pytest.mark.parametrize(
    ("field", "value"),
    [("capacity", 0), ("match_radius", -1.0), ("ban_radius", -0.5), ("max_distance", 0.0)],
)
def test_invalid_settings_name_the_field(field, value):
    with pytest.raises(ValidationError, match=field):
        LsmSettings(**{field: value})


@pytest.mark.parametrize("field", ["dist", "rough", "var", "size", "ver_alt", "normaliser"])
def test_non_finite_weights_are_refused(field):
    with pytest.raises(ValidationError, match=field):
        LossWeights(**{field: math.nan})
    with pytest.raises(ValidationError, match=field):
        LossWeights(**{field: math.inf})


def test_positions_beyond_any_mission_frame_are_rejected_before_the_drone_is_known():
    lsm = LandingSiteManager(LsmSettings(match_radius=0.01), LossWeights())
    far = SiteObservation(x=1e300, y=0.0, z=0.0, roughness=0.1, uncertainty=0.1, size=2.0,
                          obstacle_altitude=0.0, observation_altitude=30.0)
    lsm.submit(far)
    lsm.process_pending()
    assert len(lsm) == 0 and lsm.counters()["rejected_position_out_of_range"] == 1


def test_get_gives_the_record_a_ranking_gives():
    """get(id) is the ranked record of that id, every field and the loss at the current drone
    position the same, after merges, updates and moves of the drone."""
    m = manager(capacity=20)
    rng = np.random.default_rng(4)
    for step in range(30):
        x, y = rng.uniform(-40, 40, 2)
        feed(m, obs(float(x), float(y), rough=float(rng.uniform(0, 1)),
                    size=float(rng.uniform(0.5, 6)), alt=float(rng.uniform(2, 60)), t=step,
                    source=f"s{step % 3}"))
        m.set_drone_position((float(rng.uniform(-20, 20)), 0.0, 30.0))
        for site in m.ranked():
            assert m.get(site.id) == site
