"""``lander detect`` on recorded clouds and depth images, and its one-line errors."""

from __future__ import annotations

import csv

import cv2
import numpy as np
import pytest

import autonomy.cli as cli
from lsd.io import read_ply, write_ply


@pytest.fixture(autouse=True)
def only_detect(monkeypatch):
    # Isolate from other subcommands: the real main() with just this one registered.
    monkeypatch.setattr(cli, "COMMAND_MODULES", ("autonomy.cli.detect",))


def lander(*argv):
    return cli.main(["detect", *map(str, argv)])


def box_cloud(seed=0):
    """20 m square at z=0 with a 3 x 3 x 2 m box at (3, 0), 0.1 m spacing, 1 cm noise."""
    rng = np.random.default_rng(seed)
    g = np.mgrid[-10:10:0.1, -10:10:0.1].reshape(2, -1).T
    inside = (np.abs(g[:, 0] - 3) < 1.5) & (np.abs(g[:, 1]) < 1.5)
    z = np.where(inside, 2.0, 0.0) + rng.normal(0, 0.01, len(g))
    return np.c_[g, z], inside


def read_sites(out):
    with open(out / "sites.csv") as f:
        return list(csv.DictReader(f))


def assert_png(path):
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def box_distance(rows):
    xy = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    dx = np.maximum(np.abs(xy[:, 0] - 3) - 1.5, 0)
    dy = np.maximum(np.abs(xy[:, 1]) - 1.5, 0)
    return np.hypot(dx, dy)


def edge_overhang(rows, clearance=1.0):
    """How far (m) each site's clearance ring reaches beyond box_cloud's 20 m square."""
    xy = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    size = np.array([float(r["size"]) for r in rows])
    return np.abs(xy).max(axis=1) + size + clearance - 10.0


def test_npy_cloud_prints_sites_and_writes_csv_and_overlay(tmp_path, capsys):
    cloud, _ = box_cloud()
    np.save(tmp_path / "cloud.npy", cloud)
    out = tmp_path / "out"
    assert lander("--lidar", tmp_path / "cloud.npy", "--voxel", 0.1, "--seeding", "grid",
                  "--out", out) == 0
    text = capsys.readouterr().out
    assert "40000 points" in text and "sites.csv" in text
    rows = read_sites(out)
    assert len(rows) >= 5
    xy = np.array([[float(r["x"]), float(r["y"])] for r in rows])
    size = np.array([float(r["size"]) for r in rows])
    gap = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1)) - size[:, None] - size[None]
    assert (gap[~np.eye(len(rows), dtype=bool)] >= -1e-3).all()  # no two discs overlap
    assert int(rows[0]["rank"]) == 1
    scores = [float(r["score"]) for r in rows]
    assert scores == sorted(scores, reverse=True)
    assert box_distance(rows).min() >= 1.0 - 0.1  # r_min clear of the box
    assert_png(out / "overlay.png")


@pytest.mark.parametrize("binary", [True, False])
def test_ply_cloud_gives_the_same_sites_as_npy(tmp_path, binary):
    cloud, _ = box_cloud()
    np.save(tmp_path / "cloud.npy", cloud)
    write_ply(tmp_path / "cloud.ply", cloud, binary=binary)
    np.testing.assert_allclose(read_ply(tmp_path / "cloud.ply").points, cloud, atol=1e-6)
    args = ("--voxel", 0.2, "--seeding", "random", "--n-points", 30, "--seed", 4)
    assert lander("--lidar", tmp_path / "cloud.npy", "--out", tmp_path / "a", *args) == 0
    assert lander("--lidar", tmp_path / "cloud.ply", "--out", tmp_path / "b", *args) == 0
    a, b = read_sites(tmp_path / "a"), read_sites(tmp_path / "b")
    assert a and [(r["x"], r["y"]) for r in a] == [(r["x"], r["y"]) for r in b]


def test_ply_classification_is_reported_beside_each_site(tmp_path, capsys):
    cloud, inside = box_cloud()
    cls = np.where(inside, 6, 2)  # building on ground
    header = (
        f"ply\nformat ascii 1.0\ncomment made by a test\nelement vertex {len(cloud)}\n"
        "property float x\nproperty float y\nproperty float z\nproperty uchar classification\n"
        "end_header\n"
    )
    with open(tmp_path / "c.ply", "w") as f:
        f.write(header)
        np.savetxt(f, np.c_[cloud, cls], fmt=["%.4f", "%.4f", "%.4f", "%d"])
    assert lander("--lidar", tmp_path / "c.ply", "--voxel", 0.2, "--seeding", "grid",
                  "--out", tmp_path / "o") == 0
    rows = read_sites(tmp_path / "o")
    assert rows and all(r["class"].startswith("ground") for r in rows)
    assert "ground" in capsys.readouterr().out


def test_nan_rows_are_dropped_and_counted(tmp_path, capsys):
    cloud, _ = box_cloud()
    cloud[::100] = np.nan
    np.save(tmp_path / "c.npy", cloud)
    assert lander("--lidar", tmp_path / "c.npy", "--voxel", 0.2, "--out", tmp_path / "o") == 0
    assert f"({len(cloud[::100])} with NaN/inf or beyond 1e8 m dropped)" in capsys.readouterr().out


def nadir_depth():
    """640 x 480 depth from 20 m straight down at flat ground with a 2 m box."""
    depth = np.full((480, 640), 20.0, dtype=np.float32)
    depth[200:260, 300:380] = 18.0
    return depth


INTRINSICS = ("--fx", 320, "--fy", 320, "--cx", 319.5, "--cy", 239.5)


def test_depth_npy_and_16bit_png_give_the_same_sites(tmp_path, capsys):
    depth = nadir_depth()
    np.save(tmp_path / "d.npy", depth)
    assert cv2.imwrite(str(tmp_path / "d.png"), np.round(depth * 1000).astype(np.uint16))
    pose = ("--pose", "10,5,20,0")
    assert lander("--depth", tmp_path / "d.npy", *INTRINSICS, *pose, "--out", tmp_path / "a") == 0
    assert lander("--depth", tmp_path / "d.png", *INTRINSICS, *pose, "--out", tmp_path / "b") == 0
    a, b = read_sites(tmp_path / "a"), read_sites(tmp_path / "b")
    assert a and a == b
    for r in a:  # ground is at z = 0 under a camera at 20 m
        assert float(r["z"]) == pytest.approx(0.0, abs=1e-3)
    assert_png(tmp_path / "a" / "overlay.png")
    assert "640x480 depth image" in capsys.readouterr().out


def test_depth_pose_as_4x4_matrix(tmp_path):
    depth = nadir_depth()
    np.save(tmp_path / "d.npy", depth)
    m = np.eye(4)
    m[:3, :3] = [[1, 0, 0], [0, -1, 0], [0, 0, -1]]
    m[:3, 3] = [10, 5, 20]
    np.save(tmp_path / "pose.npy", m)
    assert lander("--depth", tmp_path / "d.npy", *INTRINSICS, "--pose", "10,5,20,0",
                  "--out", tmp_path / "a") == 0
    assert lander("--depth", tmp_path / "d.npy", *INTRINSICS, "--pose", tmp_path / "pose.npy",
                  "--out", tmp_path / "b") == 0
    assert read_sites(tmp_path / "a") == read_sites(tmp_path / "b")


K = {"fx": 320.0, "fy": 320.0, "cx": 319.5, "cy": 239.5}  # the intrinsics of INTRINSICS


def write_calibrations(tmp_path, distortion=(0.0, 0.0, 0.0, 0.0, 0.0), size=(640, 480)):
    """The same intrinsics as ROS camera_calibration's ost.yaml, a ROS 2 CameraInfo echoed
    as YAML, and OpenCV calibration files written by cv::FileStorage (YAML and XML)."""
    matrix = [K["fx"], 0.0, K["cx"], 0.0, K["fy"], K["cy"], 0.0, 0.0, 1.0]
    w, h = size
    (tmp_path / "ost.yaml").write_text(
        f"image_width: {w}\nimage_height: {h}\ncamera_name: depth\n"
        f"camera_matrix:\n  rows: 3\n  cols: 3\n  data: {matrix}\n"
        "distortion_model: plumb_bob\n"
        f"distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: {list(distortion)}\n"
    )
    (tmp_path / "info.yaml").write_text(  # `ros2 topic echo --once .../camera_info`
        "header:\n  stamp:\n    sec: 1\n    nanosec: 0\n  frame_id: depth_optical\n"
        f"height: {h}\nwidth: {w}\ndistortion_model: plumb_bob\n"
        + "d:\n" + "".join(f"- {c}\n" for c in distortion)
        + "k:\n" + "".join(f"- {c}\n" for c in matrix)
        + "binning_x: 0\nbinning_y: 0\n---\n"
    )
    for name in ("calib.yml", "calib.xml"):
        fs = cv2.FileStorage(str(tmp_path / name), cv2.FILE_STORAGE_WRITE)
        fs.write("image_width", w)
        fs.write("image_height", h)
        fs.write("camera_matrix", np.array(matrix).reshape(3, 3))
        fs.write("distortion_coefficients", np.array([distortion], dtype=float))
        fs.release()
    return [tmp_path / n for n in ("ost.yaml", "info.yaml", "calib.yml", "calib.xml")]


def test_intrinsics_from_ros_and_opencv_calibration_files(tmp_path, capsys):
    np.save(tmp_path / "d.npy", nadir_depth())
    pose = ("--pose", "10,5,20,0")
    assert lander("--depth", tmp_path / "d.npy", *INTRINSICS, *pose, "--out", tmp_path / "a") == 0
    expected = read_sites(tmp_path / "a")
    assert expected
    for calibration in write_calibrations(tmp_path):
        out = tmp_path / calibration.name.replace(".", "_")
        assert lander("--depth", tmp_path / "d.npy", "--camera-info", calibration, *pose,
                      "--out", out) == 0, calibration.name
        assert read_sites(out) == expected, calibration.name
    assert "distortion" not in capsys.readouterr().out  # all coefficients zero
    # A flag overrides the file: a different focal length gives other sites.
    assert lander("--depth", tmp_path / "d.npy", "--camera-info", tmp_path / "ost.yaml",
                  "--fx", 400, "--fy", 400, *pose, "--out", tmp_path / "f") == 0
    assert read_sites(tmp_path / "f") != expected


def test_a_calibration_with_distortion_is_named_and_one_for_another_size_refused(
    tmp_path, capsys
):
    np.save(tmp_path / "d.npy", nadir_depth())
    ost = write_calibrations(tmp_path, distortion=(0.1, -0.2, 0.0, 0.0, 0.0))[0]
    assert lander("--depth", tmp_path / "d.npy", "--camera-info", ost,
                  "--out", tmp_path / "a") == 0
    assert f"note: {ost} has lens distortion coefficients" in capsys.readouterr().out
    other = tmp_path / "other"
    other.mkdir()
    ost = write_calibrations(other, size=(1280, 720))[0]
    assert lander("--depth", tmp_path / "d.npy", "--camera-info", ost,
                  "--out", tmp_path / "b") == 2
    err = capsys.readouterr().err
    assert "calibrated for 1280 x 720 images, but" in err and "is 640 x 480" in err


def test_depth_scale_and_tiff_depth_images(tmp_path):
    depth = nadir_depth() / 2  # 10 m down: 50,000 units at 5000 per metre fit 16 bits
    pose = ("--pose", "10,5,10,0")
    assert lander("--depth", _save(tmp_path, "d.npy", depth), *INTRINSICS, *pose,
                  "--out", tmp_path / "a") == 0
    expected = read_sites(tmp_path / "a")
    # TUM RGB-D and Kinect v1 write 5000 units per metre; a float TIFF holds metres.
    tum = np.round(depth * 5000).astype(np.uint16)
    assert cv2.imwrite(str(tmp_path / "tum.png"), tum)
    assert cv2.imwrite(str(tmp_path / "tum.tif"), tum)
    assert cv2.imwrite(str(tmp_path / "metres.tif"), depth)
    for name, scale in (("tum.png", ["--depth-scale", 0.0002]),
                        ("tum.tif", ["--depth-scale", 0.0002]), ("metres.tif", [])):
        out = tmp_path / name.replace(".", "_")
        assert lander("--depth", tmp_path / name, *scale, *INTRINSICS, *pose,
                      "--out", out) == 0, name
        assert read_sites(out) == expected, name
    # Read as millimetres, the same image is ground 50 m down: other sites.
    assert lander("--depth", tmp_path / "tum.png", *INTRINSICS, *pose,
                  "--out", tmp_path / "mm") == 0
    assert read_sites(tmp_path / "mm") != expected


def _save(tmp_path, name, array):
    np.save(tmp_path / name, array)
    return tmp_path / name


def _png_header(width: int, height: int) -> bytes:
    """A 16-bit grey PNG's signature and header declaring ``width`` x ``height`` pixels, with
    no pixel data: whatever reads its pixels first would need gigabytes."""
    import struct
    import zlib

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(
            ">I", zlib.crc32(kind + data))

    ihdr = struct.pack(">IIBBBBB", width, height, 16, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IEND", b"")


def make_bad(tmp_path):
    """Name -> (argv, expected words in the one error line)."""
    (tmp_path / "text.ply").write_text("hello, not a cloud\n")
    (tmp_path / "text.npy").write_text("not numpy either\n")
    (tmp_path / "trunc.ply").write_bytes(
        b"ply\nformat binary_little_endian 1.0\nelement vertex 100\nproperty float x\n"
        b"property float y\nproperty float z\nend_header\n" + b"\0" * 40
    )
    np.save(tmp_path / "flat.npy", np.arange(10.0))
    np.save(tmp_path / "empty.npy", np.empty((0, 3)))
    np.save(tmp_path / "tiny.npy", np.zeros((4, 3)))
    np.save(tmp_path / "nan.npy", np.full((500, 3), np.nan))
    np.save(tmp_path / "zeros.npy", np.zeros((48, 64), dtype=np.float32))
    np.save(tmp_path / "depth.npy", nadir_depth())
    cv2.imwrite(str(tmp_path / "eight.png"), np.zeros((48, 64), dtype=np.uint8))
    (tmp_path / "fake.png").write_text("not an image")
    (tmp_path / "fake.tif").write_bytes(b"II*\0 not a TIFF")
    for side in (8000, 20000):  # beyond our limit; beyond Pillow's own too
        (tmp_path / f"huge{side}.png").write_bytes(_png_header(side, side))
    cv2.imwrite(str(tmp_path / "rgb.tif"), np.zeros((48, 64, 3), dtype=np.uint8))
    (tmp_path / "nomatrix.yaml").write_text("width: 640\nheight: 480\n")
    (tmp_path / "uncalibrated.yaml").write_text("k: [0, 0, 0, 0, 0, 0, 0, 0, 0]\n")
    (tmp_path / "short.yaml").write_text("camera_matrix:\n  rows: 3\n  data: [1, 2, 3]\n")
    (tmp_path / "broken.yaml").write_text("k: [1, 0\n  width: : 3\n")
    (tmp_path / "broken.xml").write_text("<?xml version='1.0'?>\n<opencv_storage><x>1")
    depth = tmp_path / "depth.npy"
    return {
        "ply magic": (["--lidar", tmp_path / "text.ply"], "not a PLY file"),
        "npy text": (["--lidar", tmp_path / "text.npy"], "not a NumPy"),
        "ply truncated": (["--lidar", tmp_path / "trunc.ply"], "truncated"),
        "npy shape": (["--lidar", tmp_path / "flat.npy"], "(N, 3)"),
        "empty": (["--lidar", tmp_path / "empty.npy"], "only 0 valid points"),
        "tiny": (["--lidar", tmp_path / "tiny.npy"], "only 4 valid points"),
        "all nan": (["--lidar", tmp_path / "nan.npy"], "500 with NaN/inf or beyond 1e8 m dropped"),
        "missing": (["--lidar", tmp_path / "nope.npy"], "no such file"),
        "extension": (["--lidar", tmp_path / "zeros.txt"], "no such file"),
        "las": (["--lidar", tmp_path / "x.las"], "x.las"),
        "zero depth": (["--depth", tmp_path / "zeros.npy", *INTRINSICS], "no valid depth"),
        "8-bit png": (["--depth", tmp_path / "eight.png", *INTRINSICS], "16-bit"),
        "fake png": (["--depth", tmp_path / "fake.png", *INTRINSICS], "not a readable PNG"),
        "fx zero": (["--depth", depth, "--fx", 0, "--fy", 1, "--cx", 1, "--cy", 1], "--fx"),
        "fy negative": (["--depth", depth, "--fx", 1, "--fy", -3, "--cx", 1, "--cy", 1],
                        "--fy"),
        "no intrinsics": (["--depth", depth], "--fx: required"),
        "huge png": (["--depth", tmp_path / "huge8000.png", *INTRINSICS],
                     "a 8000 x 8000 image, more than 50,000,000 pixels"),
        "huger png": (["--depth", tmp_path / "huge20000.png", *INTRINSICS],
                      "an image of more than 50,000,000 pixels"),
        "fake tif": (["--depth", tmp_path / "fake.tif", *INTRINSICS], "not a readable TIFF"),
        "rgb tif": (["--depth", tmp_path / "rgb.tif", *INTRINSICS], "single-channel TIFF"),
        "no matrix": (["--depth", depth, "--camera-info", tmp_path / "nomatrix.yaml"],
                      "no camera matrix"),
        "uncalibrated": (["--depth", depth, "--camera-info", tmp_path / "uncalibrated.yaml"],
                         "k: all zeros"),
        "short matrix": (["--depth", depth, "--camera-info", tmp_path / "short.yaml"],
                         "camera_matrix.data: expected a 3 x 3 matrix (9 numbers), got 3"),
        "broken yaml": (["--depth", depth, "--camera-info", tmp_path / "broken.yaml"],
                        "broken.yaml: line 2"),
        "broken xml": (["--depth", depth, "--camera-info", tmp_path / "broken.xml"],
                       "not a readable OpenCV calibration file"),
        "no calibration": (["--depth", depth, "--camera-info", tmp_path / "none.yaml"],
                           "cannot read"),
        "scale": (["--depth", depth, *INTRINSICS, "--depth-scale", -1], "--depth-scale"),
        "bad pose": (["--depth", depth, *INTRINSICS, "--pose", "1,2"], "--pose"),
        "both": (["--depth", depth, "--lidar", tmp_path / "empty.npy"], "exactly one"),
        "neither": ([], "exactly one"),
        "bad voxel": (["--lidar", tmp_path / "tiny.npy", "--voxel", -1], "--voxel"),
    }


def test_bad_inputs_exit_2_with_one_line(tmp_path, capsys):
    for name, (argv, words) in make_bad(tmp_path).items():
        code = lander(*argv, "--out", tmp_path / "o")
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert code == 2, name
        assert len(lines) == 1, (name, captured.err)
        assert lines[0].startswith("lander detect: error:"), name
        assert words in lines[0], (name, lines[0])
        assert "Traceback" not in captured.err


def test_las_classification_codes_are_reported(tmp_path, capsys):
    laspy = pytest.importorskip("laspy")
    cloud, inside = box_cloud()
    header = laspy.LasHeader(point_format=3, version="1.2")
    header.scales = np.array([0.001, 0.001, 0.001])
    header.offsets = np.zeros(3)
    las = laspy.LasData(header)
    las.x, las.y, las.z = cloud[:, 0], cloud[:, 1], cloud[:, 2]
    las.classification = np.where(inside, 6, 2).astype(np.uint8)
    las.write(tmp_path / "c.las")
    assert lander("--lidar", tmp_path / "c.las", "--voxel", 0.2, "--seeding", "grid",
                  "--out", tmp_path / "o") == 0
    rows = read_sites(tmp_path / "o")
    assert rows and all(r["class"].startswith("ground") for r in rows)
    assert "ground" in capsys.readouterr().out


def test_las_without_laspy_is_one_clear_line(tmp_path, capsys, monkeypatch):
    (tmp_path / "c.las").write_bytes(b"LASF" + b"\0" * 400)
    monkeypatch.setitem(__import__("sys").modules, "laspy", None)  # import fails
    assert lander("--lidar", tmp_path / "c.las", "--out", tmp_path / "o") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pip install 'landing-autonomy[las]'" in err[0]


def test_corrupt_las_is_one_clear_line(tmp_path, capsys):
    pytest.importorskip("laspy")
    (tmp_path / "bad.las").write_bytes(b"this is not a las file at all" * 10)
    assert lander("--lidar", tmp_path / "bad.las", "--out", tmp_path / "o") == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not a readable LAS/LAZ file" in err[0]


def test_noisy_depth_still_gives_sites_and_the_edge_blur_flag_is_checked(tmp_path):
    # Edges come from metric depth gradients with a noise-relative threshold, so sensor
    # noise alone does not fill the flatness map with edges, with or without more blur.
    noisy = nadir_depth() + np.random.default_rng(2).normal(0, 0.15, (480, 640))
    np.save(tmp_path / "d.npy", noisy.astype(np.float32))
    args = ("--depth", tmp_path / "d.npy", *INTRINSICS, "--pose", "0,0,20,0")
    assert lander(*args, "--out", tmp_path / "a") == 0
    assert lander(*args, "--edge-blur", 4, "--normal-window", 9, "--out", tmp_path / "b") == 0
    assert len(read_sites(tmp_path / "a")) > 0 and len(read_sites(tmp_path / "b")) > 0
    assert lander(*args, "--edge-blur", 99, "--out", tmp_path / "c") == 2  # out of range


def test_paper_flag_drops_the_checks_beyond_the_paper(tmp_path):
    cloud, _ = box_cloud()
    np.save(tmp_path / "c.npy", cloud)
    args = ("--lidar", tmp_path / "c.npy", "--voxel", 0.2, "--seeding", "grid")
    assert lander(*args, "--out", tmp_path / "ours") == 0
    assert lander(*args, "--paper", "--out", tmp_path / "paper") == 0
    ours, paper = read_sites(tmp_path / "ours"), read_sites(tmp_path / "paper")
    assert box_distance(paper).min() < box_distance(ours).min()
    # Without the coverage rule, rings run off the 20 m square (no returns taken as clear).
    assert edge_overhang(paper).max() > 1.0 and edge_overhang(ours).max() <= 0.3
