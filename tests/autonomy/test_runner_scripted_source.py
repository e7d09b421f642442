"""The scripted site source: reveal by field of view, altitude-dependent noise, verifies."""

from __future__ import annotations

import numpy as np

from autonomy.perception.scripted import ScriptedSettings, ScriptedSite, ScriptedSiteSource
from behaviors.ports import VehicleState


def source(*sites, seed=0, **settings):
    return ScriptedSiteSource(list(sites), ScriptedSettings(**settings),
                              rng=np.random.default_rng(seed))


def at(x, y, z):
    return VehicleState(position=(x, y, z))


def test_site_seen_only_inside_the_field_of_view():
    src = source(ScriptedSite(x=30.0, y=0.0), fov=90.0)
    assert src.update(at(0, 0, 20), 1.0) == []  # 30 m away, footprint radius 20 m
    (obs,) = src.update(at(0, 0, 40), 2.0)  # footprint radius 40 m
    assert obs.observation_altitude == 40.0
    assert obs.timestamp == 2.0 and obs.source == "scripted"
    events = src.drain_events()
    assert [e["event"] for e in events] == ["site_revealed"]
    assert src.drain_events() == []


def test_noise_grows_with_height_and_is_seeded():
    site = ScriptedSite(x=0.0, y=0.0)

    def spread(height):
        src = source(site, noise_base=0.0, noise_per_metre=0.02)
        xs = [src.update(at(0, 0, height), 0.0)[0].x for _ in range(400)]
        return np.std(xs)

    low, high = spread(5.0), spread(100.0)
    assert 0.05 < low < 0.15 and 1.5 < high < 2.5
    a = source(site, seed=4).update(at(0, 0, 50), 0.0)
    b = source(site, seed=4).update(at(0, 0, 50), 0.0)
    assert a == b


def test_a_site_that_does_not_verify_is_never_seen_low():
    src = source(ScriptedSite(x=0.0, y=0.0, verifies=False), low_altitude=10.0)
    assert len(src.update(at(0, 0, 30), 0.0)) == 1
    assert src.update(at(0, 0, 2.5), 1.0) == []
    good = source(ScriptedSite(x=0.0, y=0.0))
    (obs,) = good.update(at(0, 0, 2.5), 1.0)
    assert obs.observation_altitude == 2.5


def test_site_height_from_terrain_and_bad_states_dropped():
    src = ScriptedSiteSource(
        [ScriptedSite(x=10.0, y=0.0, obstacle_altitude=9.0)], rng=np.random.default_rng(1),
        height=lambda x, y: np.full(np.shape(x), 3.0),
    )
    (obs,) = src.update(at(10, 0, 23), 0.0)
    assert obs.observation_altitude == 20.0
    assert abs(obs.z - 3.0) < 1.0 and obs.obstacle_altitude == 9.0
    assert src.update(VehicleState(), 1.0) == []
    assert src.update(at(float("nan"), 0, 10), 1.0) == []
    counters = src.counters()
    assert counters["dropped_no_position"] == 1 and counters["dropped_bad_position"] == 1
    assert {e["reason"] for e in src.drain_events() if e["event"] == "perception_dropped"} == {
        "no_position", "bad_position"}
