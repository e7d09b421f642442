"""Moving obstacles (issue 18 part 4): people and vehicles on seeded paths, seen by the
sensors at the time of the frame, judged by the ground truth."""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError

from sitl.sensors import DepthCamera, DepthCameraSettings, RangeFinder
from sitl.sensors.lidar import LidarScanner, LidarSettings
from sitl.terrain import make_terrain
from sitl.terrain.contact import ContactJudge, clear_of_moving
from sitl.terrain.moving_hits import ray_hits

PERSON_AT = (10.0, 0.0)
CAR_PATH = [[0.0, 10.0], [20.0, 10.0]]  # driven back and forth at 5 m/s


def _world(**moving):
    paths = [{"kind": "person", "path": [list(PERSON_AT)]},
             {"kind": "vehicle", "path": CAR_PATH, "speed": 5.0}]
    return make_terrain({"kind": "flat", "size": [60.0, 60.0], "cell_size": 0.25,
                         "moving_obstacles": {"paths": paths, **moving}}, seed=2)


@pytest.mark.parametrize("kind", ["urban", "rubble"])
def test_random_obstacles_leave_the_static_world_as_it_was(kind):
    settings = {"kind": kind, "size": [200.0, 200.0]}
    still = make_terrain(settings, seed=4)
    busy = make_terrain({**settings, "moving_obstacles": {"count": 12}}, seed=4)
    assert still.moving is None
    assert np.array_equal(still.grid, busy.grid)
    assert len(busy.moving) == 12
    again = make_terrain({**settings, "moving_obstacles": {"count": 12}}, seed=4)
    a, b = busy.moving.at(37.5), again.moving.at(37.5)
    assert np.array_equal(a.x, b.x) and np.array_equal(a.y, b.y)
    # they walk on the ground (not on roofs), at their speeds
    assert np.all(a.base <= 1.0 + busy.height(a.x, a.y))
    later = busy.moving.at(38.5)
    step = np.hypot(later.x - a.x, later.y - a.y)
    assert np.all(step <= busy.moving.speed + 1e-9)
    assert np.any(step > 0.5)


def test_in_a_town_random_vehicles_drive_on_the_roads_along_the_street_grid():
    terrain = make_terrain({"kind": "urban", "size": [300.0, 300.0], "moving_obstacles": {
        "count": 30, "vehicle_fraction": 0.5}}, seed=5)
    moving = terrain.moving
    road = float(terrain.grid.min())
    driven = 0
    for obstacle in moving.describe():
        path = np.asarray(obstacle["path"])
        if obstacle["kind"] != "vehicle" or len(path) < 2:
            continue
        driven += 1
        assert np.all(np.min(np.abs(np.diff(path, axis=0)), axis=1) < 1e-6)  # x or y
        if obstacle["closed"]:  # and the way back round, on the road too
            path = np.vstack([path, path[:1]])
        legs = np.diff(path, axis=0)
        f = np.linspace(0.0, 1.0, 100)[:, None, None]
        across = np.stack([-legs[:, 1], legs[:, 0]], axis=1) / np.maximum(
            np.hypot(*legs.T), 1e-12)[:, None]  # unit normals of the legs
        for side in (-1.0, 0.0, 1.0):  # the centre line and both sides of a 2 m car
            xy = (path[:-1] + f * legs + side * across).reshape(-1, 2)
            assert terrain.height(xy[:, 0], xy[:, 1]).max() <= road + 0.1  # never a kerb
    assert driven >= 10


def test_a_car_drives_its_path_back_and_forth_as_a_function_of_time():
    moving = _world().moving
    at = {t: moving.at(t) for t in (0.0, 1.0, 4.0, 5.0, 9.0)}
    assert [at[t].x[1] for t in at] == pytest.approx([0.0, 5.0, 20.0, 15.0, 5.0])
    assert at[1.0].heading[1] == pytest.approx(0.0)  # eastward out ...
    assert abs(at[5.0].heading[1]) == pytest.approx(np.pi)  # ... westward back
    assert at[9.0].x[0] == PERSON_AT[0]  # the person stands


def test_the_depth_camera_sees_a_person_and_a_passing_car_at_the_frame_time():
    terrain = _world()
    camera = DepthCamera(terrain, DepthCameraSettings(width=80, height=80, focal_px=40.0,
                                                      noise=False))
    # straight above the person: the centre pixel ends on its head, 1.8 m above ground
    frame = camera.render((PERSON_AT[0], PERSON_AT[1], 10.0), 0.0, 0.0, agl=10.0)
    assert frame.depth[40, 40] == pytest.approx(8.2, abs=1e-3)
    snapshot, index = frame.moving
    assert index[40, 40] == 0
    # above the car's path: at t = 2 s it is below (x = 10), at t = 0 it is 10 m away
    above = (10.0, 10.0, 10.0)
    passing = camera.render(above, 0.0, 2.0, agl=10.0)
    assert passing.depth[40, 40] == pytest.approx(8.4, abs=1e-3)
    assert passing.moving[1][40, 40] == 1
    gone = camera.render(above, 0.0, 0.0, agl=10.0)
    assert gone.depth[40, 40] == pytest.approx(10.0, abs=1e-3)


def test_without_moving_obstacles_the_frames_are_the_same_as_before():
    settings = {"kind": "flat", "size": [60.0, 60.0], "cell_size": 0.25}
    still = make_terrain(settings, seed=2)
    empty = make_terrain({**settings, "moving_obstacles": {"count": 0}}, seed=2)
    assert empty.moving is None
    cams = [DepthCamera(t, DepthCameraSettings(width=40, height=40, focal_px=20.0),
                        rng=np.random.default_rng(1)) for t in (still, empty)]
    a, b = (c.render((3.0, 4.0, 12.0), 0.3, 1.0, agl=12.0) for c in cams)
    assert np.array_equal(a.depth, b.depth, equal_nan=True) and a.moving is None


def test_lidar_and_range_finder_return_off_the_obstacles_when_given_the_time():
    terrain = _world()
    finder = RangeFinder(terrain, rng=np.random.default_rng(0))
    finder.settings = finder.settings.model_copy(update={"noise_std": 0.0})
    over_person = (PERSON_AT[0], PERSON_AT[1], 5.0)
    assert finder.measure(over_person, time=3.0) == pytest.approx(3.2)
    assert finder.measure(over_person) == pytest.approx(5.0)  # no time: the ground only
    lidar = LidarScanner(terrain, LidarSettings(pattern="downward", channels=9,
                                                azimuth_steps=9, vertical_fov_deg=10.0,
                                                range_noise_std=0.0))
    points = lidar.scan((10.0, 10.0, 6.0), 0.0, time=2.0)  # the car below
    assert points[:, 2].max() == pytest.approx(1.6, abs=1e-6)
    assert lidar.scan((10.0, 10.0, 6.0), 0.0, time=0.0)[:, 2].max() == pytest.approx(0.0)


def test_rays_meet_boxes_and_cylinders_where_geometry_says():
    snapshot = _world().moving.at(2.0)  # car centred at (10, 10), heading east
    # level rays at 1 m height: the car's west face at x = 7.75, the person at x = 9.7
    t, index = ray_hits(snapshot, (0.0, 10.0, 1.0), np.array([1.0]), np.array([0.0]),
                        np.array([0.0]))
    assert t[0] == pytest.approx(7.75) and index[0] == 1
    t, index = ray_hits(snapshot, (0.0, 0.0, 1.0), np.array([1.0]), np.array([0.0]),
                        np.array([0.0]))
    assert t[0] == pytest.approx(9.7) and index[0] == 0
    t, _ = ray_hits(snapshot, (0.0, 0.0, 2.0), np.array([1.0]), np.array([0.0]),
                    np.array([0.0]))  # over the person's head
    assert np.isnan(t[0])


def test_contacts_and_touchdowns_near_moving_obstacles_are_judged():
    terrain = _world()
    judge = ContactJudge(terrain)
    assert judge.contact((PERSON_AT[0] + 1.2, PERSON_AT[1], 1.0), 0.0).obstacle == "person"
    assert judge.contact((PERSON_AT[0] + 1.4, PERSON_AT[1], 1.0), 0.0) is None  # 1.1 m off
    assert judge.contact((PERSON_AT[0], PERSON_AT[1], 1.9), 0.0) is None  # above its head
    assert judge.contact((10.0, 10.0, 0.5), 2.0).obstacle == "vehicle"
    assert judge.contact((10.0, 10.0, 0.5), 0.0) is None
    assert not clear_of_moving(terrain, PERSON_AT[0] + 1.7, PERSON_AT[1], 0.0)
    assert clear_of_moving(terrain, PERSON_AT[0] + 1.9, PERSON_AT[1], 0.0)


def test_raised_terrain_within_the_rotor_disc_is_a_collision():
    terrain = make_terrain({"kind": "flat", "size": [40.0, 40.0], "cell_size": 0.25}, seed=0)
    terrain.grid[np.ix_(range(100, 120), range(100, 120))] = 5.0  # a block, x, y 5 .. 10 m
    judge = ContactJudge(terrain)
    assert judge.contact((4.3, 7.0, 1.0), 0.0).obstacle == "terrain"  # rotors in its wall
    assert judge.contact((3.8, 7.0, 1.0), 0.0) is None
    assert judge.contact((7.0, 7.0, 5.7), 0.0) is None  # on top of it


@pytest.mark.parametrize(("moving", "field"), [
    ({"count": -1}, "count"),
    ({"person_speed": [2.0, 1.0]}, "person_speed"),
    ({"paths": [{"kind": "cat", "path": [[0, 0]]}]}, "kind"),
    ({"paths": [{"kind": "person", "path": [[500.0, 0.0]]}]}, "moving_obstacles.paths.0"),
    ({"paths": [{"kind": "person", "path": []}]}, "path"),
    ({"count": 400, "paths": [{"kind": "person", "path": [[0, 0]]}] * 101}, "count"),
])
def test_bad_moving_obstacle_settings_name_the_field(moving, field):
    with pytest.raises(ValidationError) as err:
        make_terrain({"kind": "urban", "size": [200.0, 200.0], "moving_obstacles": moving})
    assert field in str(err.value)


def test_the_greyscale_frames_show_a_car_moving_and_the_ground_still():
    import cv2

    from sitl.sensors.intensity import render_intensity
    from sitl.terrain.albedo import AlbedoMap

    terrain = _world()
    camera = DepthCamera(terrain, DepthCameraSettings(width=160, height=120, focal_px=80.0,
                                                      noise=False))
    albedo = AlbedoMap(terrain, np.random.default_rng(0))
    pose = ((10.0, 10.0, 10.0), 0.0)  # above the car's lane, heading east (image up)
    first, second = (camera.render(*pose, t, agl=10.0) for t in (1.5, 1.75))
    frames = [render_intensity(f, albedo, np.random.default_rng(1)) for f in (first, second)]
    corners = cv2.goodFeaturesToTrack(frames[0], 400, 0.01, 3).reshape(-1, 2)
    moved, status, _ = cv2.calcOpticalFlowPyrLK(frames[0], frames[1], corners, None)
    ok = status.ravel() == 1
    flow = (moved.reshape(-1, 2) - corners)[ok]
    u, v = corners[ok].T.astype(int)
    on_car = first.moving[1][v, u] == 1
    assert on_car.sum() >= 5 and (~on_car).sum() >= 20
    # 1.25 m east in 0.25 s, 8.4 m below the camera: 80 * 1.25 / 8.4 = 11.9 px up the image
    assert np.median(flow[on_car, 1]) == pytest.approx(-80 * 1.25 / 8.4, abs=1.5)
    assert np.median(np.abs(flow[~on_car])) < 0.3


def test_the_simulators_range_finder_reads_the_roof_of_a_car_passing_below():
    from pymavlink.dialects.v20 import ardupilotmega as mavlink

    from sitl import MemoryLink, Sitl
    from sitl.copter.gcs import MiniGcs

    sim = Sitl(terrain=_world())
    link = MemoryLink()
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)

    def run(seconds, every=None):
        end = sim.time + seconds
        while sim.time < end - 1e-9:
            sim.step(0.05)
            gcs.poll()
            if every is not None:
                every()

    gcs.heartbeat()
    run(sim.settings.arming_settle_time + 0.1)
    gcs.set_mode(4)  # GUIDED
    gcs.arm()
    gcs.takeoff(10.0)
    gcs.set_interval(mavlink.MAVLINK_MSG_ID_DISTANCE_SENSOR, 20)
    run(15.0)
    gcs.goto_ned(10.0, 10.0, -10.0)  # above the middle of the car's lane (ENU x 10, y 10)
    run(15.0)
    readings = []
    run(8.0, lambda: readings.append(gcs.last["DISTANCE_SENSOR"].current_distance))
    x, y, z = sim.truth.position
    assert (x, y, z) == pytest.approx((10.0, 10.0, 10.0), abs=0.3)
    # the ground 10 m below, the car's 1.6 m roof when it passes (twice in 8 s)
    assert max(readings) == pytest.approx(100 * z, abs=3)
    assert min(readings) == pytest.approx(100 * (z - 1.6), abs=3)
