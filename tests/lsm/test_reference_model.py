"""The manager against a deliberately simple reference: a plain list re-sorted every step."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import lsm.manager
from lsm import LandingSiteManager, LossWeights, LsmSettings, SiteObservation, site_loss

SETTINGS = LsmSettings(capacity=4, match_radius=2.0, max_distance=60.0, ban_radius=3.0,
                       rekey_distance=1e-9)  # re-key on every move: exact eviction
WEIGHTS = LossWeights(dist=1.0, rough=1.0, var=0.5, size=1.0, ver_alt=0.7, normaliser=100.0)


class ReferenceLsm:
    """Every rule of DESIGN.md section 4 written the obvious, slow way."""

    def __init__(self):
        self.sites: list[dict] = []
        self.bans: list[tuple[float, float, float]] = []
        self.drone = None
        self.next_id = 1

    def dist(self, s):
        if self.drone is None:
            return 0.0
        dx, dy = s["x"] - self.drone[0], s["y"] - self.drone[1]
        return math.sqrt(dx * dx + dy * dy)

    def losses(self, sites, size_max):
        return site_loss(np.array([self.dist(s) for s in sites]),
                         np.array([s["rough"] for s in sites]),
                         np.array([s["unc"] for s in sites]),
                         np.array([s["size"] for s in sites]),
                         np.array([s["veralt"] for s in sites]), size_max, WEIGHTS)

    def ranked_records(self):
        by_id = {s["id"]: s for s in self.sites}
        return [(i, by_id[i]["x"], by_id[i]["y"], by_id[i]["rough"], by_id[i]["size"],
                 by_id[i]["veralt"]) for i in self.ranking()]

    def ranking(self):
        if not self.sites:
            return []
        size_max = max(s["size"] for s in self.sites)
        loss = self.losses(self.sites, size_max)
        return [s["id"] for _, s in sorted(zip(loss.tolist(), self.sites, strict=True),
                                           key=lambda p: (p[0], p[1]["id"]))]

    def move(self, p):
        self.drone = p
        self.sites = [s for s in self.sites if self.dist(s) <= SETTINGS.max_distance]

    def ban(self, site_id):
        for s in self.sites:
            if s["id"] == site_id:
                self.bans.append((s["x"], s["y"], SETTINGS.ban_radius))
                self.sites.remove(s)
                return

    def submit(self, o: SiteObservation):
        if any((o.x - bx) ** 2 + (o.y - by) ** 2 <= r * r for bx, by, r in self.bans):
            return
        new = {"x": o.x, "y": o.y, "rough": o.roughness, "unc": o.uncertainty,
               "size": o.size, "veralt": o.observation_altitude}
        if self.drone is not None and self.dist(new) > SETTINGS.max_distance:
            return
        near = [(((s["x"] - o.x) * (s["x"] - o.x) + (s["y"] - o.y) * (s["y"] - o.y)), s["id"], s)
                for s in self.sites]
        near = [n for n in near if n[0] <= SETTINGS.match_radius ** 2]
        if near:
            s = min(near, key=lambda n: (n[0], n[1]))[2]
            if o.observation_altitude < s["veralt"]:
                s.update(new)
            return
        if len(self.sites) >= SETTINGS.capacity:
            size_max = max([s["size"] for s in self.sites] + [o.size])
            loss = self.losses(self.sites + [new], size_max).tolist()
            worst = max(range(len(self.sites)), key=lambda i: (loss[i], self.sites[i]["id"]))
            if not loss[-1] < loss[worst]:
                return
            del self.sites[worst]
        new["id"] = self.next_id
        self.next_id += 1
        self.sites.append(new)


# Coarse coordinates make redetections, ties and evictions frequent.
coord = st.one_of(st.integers(-12, 12).map(float),
                  st.floats(-80, 80, allow_nan=False).map(lambda v: round(v, 1)))
unit = st.one_of(st.sampled_from([0.0, 0.25, 0.5, 1.0]), st.floats(0, 1))
observation = st.builds(
    lambda x, y, r, u, size, alt: SiteObservation(x, y, 0.0, r, u, size, 1.0, alt),
    coord, coord, unit, unit,
    st.one_of(st.integers(0, 8).map(float), st.floats(0, 8)),
    st.one_of(st.sampled_from([2.5, 40.0, 100.0]), st.floats(0, 120)),
)
step = st.one_of(
    st.tuples(st.just("obs"), observation),
    st.tuples(st.just("obs"), observation),
    st.tuples(st.just("obs"), observation),
    st.tuples(st.just("move"), st.tuples(coord, coord)),
    st.tuples(st.just("ban"), st.integers(0, 10)),
)


@pytest.fixture(params=["hash", "tree"])
def lookup(request, monkeypatch):
    """Run the property both with the redetection lookup in the spatial hash only (small
    stores) and through the snapshot of sites rebuilt at every batch."""
    if request.param == "tree":
        monkeypatch.setattr(lsm.manager, "_SNAPSHOT_MIN", -1)
    return request.param


@settings(max_examples=300, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(steps=st.lists(step, min_size=5, max_size=60))
# Found by this test: a ban lowers size_max, a site keyed under the lower size_max joins the
# heap, then a large newcomer restores the old size_max and the eviction used the stale key.
@example(steps=[("obs", SiteObservation(0.0, y, 0.0, 0.0, 0.0, size, 1.0, 2.5))
                for y, size in ((0.0, 0.0), (0.0, 0.0), (3.0, 4.0), (6.0, 0.0), (-6.0, 0.0),
                                (9.0, 0.0))]
         + [("ban", 0), ("obs", SiteObservation(0.0, -3.0, 0.0, 0.0, 0.0, 1.0, 1.0, 40.0)),
            ("obs", SiteObservation(0.0, 9.0, 0.0, 0.0, 0.0, 4.0, 1.0, 2.5))])
def test_same_retained_sites_and_ranking_as_the_reference(lookup, steps):
    m = LandingSiteManager(SETTINGS, WEIGHTS)
    ref = ReferenceLsm()
    for kind, arg in steps:
        if kind == "obs":
            m.submit(arg)
            m.process_pending()
            ref.submit(arg)
        elif kind == "move":
            m.set_drone_position((arg[0], arg[1], 100.0))
            ref.move((arg[0], arg[1], 100.0))
        else:
            ranking = ref.ranking()
            if ranking:
                site_id = ranking[arg % len(ranking)]
                assert m.ban(site_id)
                ref.ban(site_id)
        assert [(s.id, s.x, s.y, s.roughness, s.size, s.verification_altitude)
                for s in m.ranked()] == ref.ranked_records()
        assert len(m) <= SETTINGS.capacity
