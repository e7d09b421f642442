"""An elevation model read from a file is taken as it is: outside its grid and on its nodata
cells there is no ground, so the depth camera, the LiDAR and the range finder get no return
there, and no landing site can be detected there (issue 16: flights over a real model used
to land on the flat extrusion beyond its edge)."""

from __future__ import annotations

import numpy as np
import pytest

from autonomy.perception.camera import to_depth_frame
from lsd.elevation.detector import ElevationDetector
from sitl.sensors import DepthCamera, DepthCameraSettings
from sitl.sensors.lidar import LidarScanner, LidarSettings
from sitl.sensors.rangefinder import RangeFinder
from sitl.terrain import FileTerrainSettings, is_safe, make_terrain

NODATA = -9999.0
CELL = 0.5  # the model's own cell size (m)


def write_asc(path, heights, cell=CELL, nodata=NODATA):
    """ESRI ASCII grid, rows north to south as the format has them."""
    ny, nx = heights.shape
    with open(path, "w") as f:
        f.write(f"ncols {nx}\nnrows {ny}\nxllcorner 0\nyllcorner 0\ncellsize {cell}\n")
        f.write(f"NODATA_value {nodata}\n")
        np.savetxt(f, heights[::-1], fmt="%.3f")


@pytest.fixture
def model(tmp_path):
    """A 40 m x 40 m flat model with a 5 m x 5 m nodata hole centred 10 m east of home."""
    heights = np.zeros((81, 81))
    heights[35:46, 55:66] = NODATA  # x, y in 27.5 .. 32.5 m from the south-west corner
    path = tmp_path / "model.asc"
    write_asc(path, heights)
    settings = FileTerrainSettings(path=path, cell_size=0.25, home_clear_radius=0.0)
    return make_terrain(settings)


def test_the_model_has_ground_only_on_its_known_cells(model):
    xmin, xmax, ymin, ymax = model.extent
    assert (xmin, xmax, ymin, ymax) == (-20.0, 20.0, -20.0, 20.0)
    assert model.has_ground(0.0, 0.0)
    assert not model.has_ground(10.0, 0.0)  # the nodata hole
    assert not model.has_ground(25.0, 0.0)  # off the model
    assert not model.has_ground(0.0, -20.5)
    # Ground truth: no touchdown is safe where the model knows no ground.
    assert not is_safe(model, 10.0, 0.0) and not is_safe(model, 25.0, 0.0)
    assert is_safe(model, -5.0, 0.0)


def test_the_depth_camera_sees_nothing_off_the_model_or_on_nodata(model):
    camera = DepthCamera(model, DepthCameraSettings(noise=False))
    position = np.array([12.0, 0.0, 20.0])
    frame = camera.render(position, yaw=0.0, timestamp=0.0, agl=20.0)
    assert frame is not None
    # Where each pixel's ray meets the level z = 0 plane (the model is flat).
    v, u = np.mgrid[0 : frame.height, 0 : frame.width]
    rays = np.stack(((u - frame.cx) / frame.fx, (v - frame.cy) / frame.fy, np.ones(u.shape)), -1)
    ground = position + (rays @ frame.rotation.T) * 20.0
    on_model = model.has_ground(ground[..., 0], ground[..., 1])
    assert on_model.any() and (~on_model).any()  # the view spans the edge and the hole
    assert np.all(np.isnan(frame.depth[~on_model]))
    # Known ground returns its depth (cells next to the hole and the edge aside).
    inner = on_model & (np.abs(ground[..., 0]) < 19.0) & (np.hypot(ground[..., 0] - 10.0,
                                                                    ground[..., 1]) > 4.0)
    np.testing.assert_allclose(frame.depth[inner], 20.0, atol=1e-3)


def test_elevation_map_detects_no_site_off_the_model_or_on_nodata(model):
    camera = DepthCamera(model, DepthCameraSettings(noise=False))
    detector = ElevationDetector()
    sites = []
    for k, x in enumerate(np.linspace(5.0, 15.0, 6)):
        frame = camera.render(np.array([x, 0.0, 12.0]), yaw=0.0, timestamp=float(k), agl=12.0)
        if frame is not None:
            sites += detector.process(to_depth_frame(frame))
    assert sites, "the known part of the model is flat ground"
    xy = np.array([s.position[:2] for s in sites])
    assert np.all(model.has_ground(xy[:, 0], xy[:, 1]))


def test_lidar_and_rangefinder_get_no_return_off_the_model(model):
    scan = LidarScanner(model, LidarSettings(pattern="downward", channels=60, azimuth_steps=60,
                                             vertical_fov_deg=90.0, range_noise_std=0.0))
    points = scan.scan([15.0, 0.0, 15.0], 0.0)
    assert len(points) > 0
    assert np.all(model.has_ground(points[:, 0], points[:, 1]))
    assert points[:, 0].max() <= 20.0 + 1e-6
    assert len(points) < 60 * 60  # rays beyond the east edge and into the hole: no point
    rangefinder = RangeFinder(model)
    assert rangefinder.measure([0.0, 0.0, 10.0]) is not None
    assert rangefinder.measure([10.0, 0.0, 10.0]) is None  # over nodata
    assert rangefinder.measure([30.0, 0.0, 10.0]) is None  # off the model


def test_a_model_of_nodata_only_is_refused_in_one_line(tmp_path):
    path = tmp_path / "empty.asc"
    write_asc(path, np.full((5, 5), NODATA))
    with pytest.raises(ValueError, match="no valid heights"):
        FileTerrainSettings(path=path, cell_size=0.25, home_clear_radius=0.0)


def test_a_flight_over_a_real_elevation_model_lands_on_it(tmp_path):
    """The USGS DEM matplotlib ships (Jacksboro fault, Tennessee), a 41 x 51 cell crop at
    1:74 scale (1 m cells, heights / 74: its real relief and slopes on a 40 m x 50 m
    model), flown with the elevation-map detector from a camera that sees past the edge."""
    import matplotlib.cbook as cbook

    from autonomy.config import parse_mission
    from autonomy.runner import fly

    dem = cbook.get_sample_data("jacksboro_fault_dem.npz")["elevation"][110:161, 270:311]
    np.save(tmp_path / "dem.npy", np.asarray(dem, dtype=np.float32)[::-1])  # south first
    mission = parse_mission(
        f"""\
cruise_altitude: 15.0
waypoints:
  - [8.0, 0.0, 15.0]
landing: {{verification_duration: 6.0, search_rectangle: [10, 10],
          pattern_center_radius: 2.0}}
world: {{kind: file, path: {tmp_path / "dem.npy"}, source_cell_size: 1.0,
        vertical_scale: 0.0135, cell_size: 0.25, home_clear_radius: 3.0}}
lsm: {{match_radius: 3.0}}
sitl: {{arming_settle_time: 2.0}}
perception:
  detector: elevation_map
  rate: 1.0
  camera: {{width: 64, height: 64, focal_px: 32.0}}
  elevation_map: {{size: 30.0, resolution: 0.5, fine_below: 0.0}}
seed: 3
""",
        "dem.yaml",
    )
    result = fly(mission, report_png=False)
    summary = result.summary
    terrain = make_terrain(mission.world)
    assert summary["outcome"] == "landed", summary["outcome"]
    touchdown = summary["touchdown"]
    assert terrain.has_ground(touchdown["x"], touchdown["y"])
