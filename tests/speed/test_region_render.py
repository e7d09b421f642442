"""Rendering only the pixels that can matter to the elevation map (issue 21, lever A): the
depth camera skips the image tiles whose points (noise included) cannot land in the maps'
window, and the map, the sites and the depths it keeps are those of the whole image."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from autonomy.config import load_mission
from autonomy.perception.camera import to_depth_frame
from autonomy.perception.elevation import ElevationMapSource
from autonomy.runner.world import FlightSeeds, build_terrain
from sitl.sensors.region import GroundRegion

ROOT = Path(__file__).resolve().parents[2]

# Camera (x, y, z, yaw, time): a cruise leg at 100 m (SfM needs lateral motion), then the
# descent to the verification height (where the whole view lies inside the map).
POSES = [
    (20.0, -60.0, 100.0, 0.0, 10.0),
    (40.0, -60.0, 100.0, 0.0, 11.0),
    (60.0, -59.0, 100.0, 0.7, 12.0),
    (75.0, -50.0, 100.0, 2.0, 13.0),
    (100.0, 40.0, 30.0, 1.2, 40.0),
    (101.0, 40.5, 12.0, 1.3, 44.0),
]


@pytest.fixture(scope="module")
def flights():
    """The same frames through a source rendering whole images and one rendering only the
    needed pixels, over the Mars mission's seed-0 world, same noise seeds."""
    mission = load_mission(ROOT / "missions" / "mars_science.yaml")
    seeds = FlightSeeds.derive(0)
    terrain = build_terrain(mission, seeds.terrain)
    p = mission.perception

    def source(needed_only: bool) -> ElevationMapSource:
        s = ElevationMapSource.from_settings(
            terrain, rng=np.random.default_rng(seeds.perception), camera=p.camera,
            rangefinder=p.rangefinder, elevation_map=p.elevation_map, detector=p.detection,
        )
        s.render_needed_only = needed_only
        return s

    whole, needed = source(False), source(True)
    out = []
    for x, y, z, yaw, t in POSES:
        frames = []
        for s in (whole, needed):
            position = np.array([x, y, z])
            region = s.ground_needed(position)
            rendered = s.camera.render(position, yaw, t, region=region)
            sites = s.detect(to_depth_frame(rendered)) if rendered is not None else None
            maps = (s.detector.map, s.detector.fine_map)
            frames.append((rendered, sites, [(m.mean.copy(), m.variance.copy(), m.top.copy(),
                                              m.closest.copy()) for m in maps], region))
        out.append(frames)
    return out


def test_cruise_frames_render_less_than_half_the_image(flights):
    fractions = [needed[0].rendered.mean() for _, needed in flights[1:4]]
    assert all(f < 0.5 for f in fractions), fractions
    # Low down the whole view lies in the map: every pixel is rendered.
    assert flights[-1][1][0].rendered is None


def test_rendered_pixels_keep_their_depths(flights):
    for whole, needed in flights:
        if whole[0] is None:
            assert needed[0] is None
            continue
        mask = needed[0].rendered
        if mask is None:
            mask = np.ones(whole[0].depth.shape, bool)
        a, b = whole[0].depth[mask], needed[0].depth[mask]
        assert np.array_equal(np.isnan(a), np.isnan(b))
        # Only the refinement's stopping point may move, within its tolerance (1 mm at
        # the coarser level of detail used at cruise, plus the noise's scaling).
        assert np.nanmax(np.abs(a - b)) <= 2e-3
        assert np.all(np.isnan(needed[0].depth[~mask]))


def test_maps_and_sites_are_those_of_the_whole_image(flights):
    for whole, needed in flights:
        for grids_whole, grids_needed in zip(whole[2], needed[2], strict=True):
            for a, b in zip(grids_whole, grids_needed, strict=True):
                np.testing.assert_array_equal(a, b)
        if whole[1] is not None:
            assert [dataclasses.asdict(s) for s in whole[1]] == [
                dataclasses.asdict(s) for s in needed[1]
            ]


def test_skipped_pixels_would_have_landed_outside_the_window(flights):
    """The whole image's points from the pixels the region render skipped, placed as the
    detector places them (5 x 5 box-smoothed depth), all fall outside the ground box."""
    import cv2

    for whole, needed in flights[1:4]:
        r, mask = whole[0], needed[0].rendered
        region = needed[3]
        assert isinstance(region, GroundRegion)
        x0, x1, y0, y1 = region.x_min, region.x_max, region.y_min, region.y_max
        placement = cv2.blur(r.depth, (5, 5))
        v, u = np.mgrid[0 : r.height, 0 : r.width]
        ray = r.rotation @ np.stack([(u - r.cx) / r.fx, (v - r.cy) / r.fy, np.ones(u.shape)]
                                    ).reshape(3, -1)
        x = r.position[0] + placement.reshape(-1) * ray[0]
        y = r.position[1] + placement.reshape(-1) * ray[1]
        skipped = ~mask.reshape(-1) & np.isfinite(x)
        inside = (x >= x0) & (x < x1) & (y >= y0) & (y < y1)
        assert not np.any(inside & skipped)
        assert np.any(inside)
