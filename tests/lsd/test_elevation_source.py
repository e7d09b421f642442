"""The elevation-map site source over the simulated world, and the detector's precision
against the ground-truth safety of the Mars world."""

from __future__ import annotations

import numpy as np
import pytest

from autonomy.perception.base import SiteSource
from autonomy.perception.elevation import ElevationMapSource
from behaviors.ports import VehicleState
from sitl.terrain import is_safe, make_terrain


@pytest.fixture(scope="module")
def flat_world():
    return make_terrain({"kind": "flat", "size": [200.0, 200.0]}, seed=1)


def test_source_reports_sites_from_the_reported_pose(flat_world):
    source: SiteSource = ElevationMapSource.from_settings(flat_world, rng=np.random.default_rng(4))
    observations = []
    for k in range(3):  # hovering at 8 m: the stereo camera needs no motion
        state = VehicleState(time=k * 0.5, position=(10.0, -5.0, 8.0), yaw=0.4)
        observations = source.update(state, now=k * 0.5)
    assert observations
    for o in observations:
        assert abs(o.z) < 0.05
        assert o.observation_altitude >= 7.5
        assert o.source == "elevation:stereo"
        assert o.timestamp == 1.0
    # Sites lie under the camera (8 m up, 53 deg field of view: +-4 m).
    xy = np.array([(o.x, o.y) for o in observations])
    assert np.all(np.hypot(xy[:, 0] - 10.0, xy[:, 1] + 5.0) < 6.0)
    events = source.drain_events()
    assert {"event": "depth_source", "source": "stereo"}.items() <= events[0].items()
    assert source.counters()["observations"] >= len(observations)


def test_source_without_a_pose_or_frame_returns_nothing(flat_world):
    source = ElevationMapSource.from_settings(flat_world, rng=np.random.default_rng(4))
    assert source.update(VehicleState(position=None), now=0.0) == []
    # At cruise altitude structure from motion needs lateral motion first.
    assert source.update(VehicleState(position=(0.0, 0.0, 100.0)), now=0.5) == []
    assert source.update(VehicleState(position=(0.0, 0.0, float("nan"))), now=1.0) == []
    counters = source.counters()
    assert counters["no_position"] == 1
    assert counters["no_frame"] == 2
    reasons = [e.get("reason") for e in source.drain_events()]
    assert "sfm_baseline" in reasons


def test_cruise_flight_gives_uncertain_sites_from_structure_from_motion(flat_world):
    source = ElevationMapSource.from_settings(flat_world, rng=np.random.default_rng(2))
    observations = []
    for k in range(8):  # 8 m/s eastwards at 100 m, 2 Hz
        t = 0.5 * k
        observations = source.update(VehicleState(position=(-30.0 + 4.0 * t * 2, 0.0, 100.0)), t)
    assert observations
    assert all(o.source == "elevation:sfm" for o in observations)
    assert all(o.observation_altitude > 95 for o in observations)
    assert np.median([o.uncertainty for o in observations]) > 0.2


@pytest.fixture(scope="module")
def mars_flight():
    """Observations of a short Mars mission: a cruise pass at 100 m, then stereo descents to
    2.5 m over the four best sites the pass found; with the ground-truth safety of each."""
    world = make_terrain({"kind": "mars", "size": [240.0, 240.0]}, seed=23)
    source = ElevationMapSource.from_settings(world, rng=np.random.default_rng(23))
    seen = []
    t = 0.0
    for k in range(12):  # 8 m/s at 2 Hz
        t += 0.5
        seen += source.update(VehicleState(position=(-40.0 + 4.0 * k, 5.0, 100.0)), t)
    assert seen, "the cruise pass found no site"
    best = sorted(seen, key=lambda o: o.roughness + o.uncertainty - o.size / 10.0)
    chosen = []
    for o in best:
        if all(np.hypot(o.x - c.x, o.y - c.y) > 10.0 for c in chosen):
            chosen.append(o)
    for site in chosen[:4]:
        for height in (15.0, 11.0, 8.0, 6.0, 4.5, 3.5, 3.0, 2.5, 2.5):
            t += 0.5
            state = VehicleState(position=(site.x, site.y, site.z + height))
            seen += source.update(state, t)
        t += 60.0  # fly on
    safe = is_safe(world, [o.x for o in seen], [o.y for o in seen])
    altitude = np.array([o.observation_altitude for o in seen])
    return altitude, np.asarray(safe, dtype=bool)


def test_sites_seen_from_below_5_m_are_safe_on_mars(mars_flight):
    altitude, safe = mars_flight
    low = altitude < 5.0
    assert low.sum() >= 4, "descents to 2.5 m must re-detect sites"
    assert safe[low].mean() >= 0.99


def test_sites_seen_from_cruise_altitude_are_mostly_safe_on_mars(mars_flight):
    altitude, safe = mars_flight
    high = altitude > 60.0
    assert high.sum() >= 20
    # Well above the world's safe share (about a third), though noisy from 100 m.
    assert safe[high].mean() >= 0.6
