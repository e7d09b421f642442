"""``lander detect --lidar``: ground with no returns is unknown, not clear (max_gap). A site's
disc and clearance ring must be covered by returns; a clear patch beside a hole (water, the
edge of the data) holds no site whose ring reaches over the hole, the same patch with the
hole filled does, and a sparse but complete scan still counts as covered."""

from __future__ import annotations

import csv

import numpy as np
import pytest

from lsd.io import write_las
from lsd.lidar_pca.judge import Judge, JudgeRules
from lsd.lidar_pca.settings import LidarPcaSettings
from tests.lsd.detect_cli import lander, only_detect  # noqa: F401 - only_detect is autouse

CLEARANCE = 1.0  # the default clearance ring (obstacle_margin), m
CLEAR_X = (10.0, 16.0)  # the clear flat patch, x (m); y 8 .. 22
HOLE_X = (16.0, 23.0)  # no returns here (or flat ground, filled)


def read_sites(out):
    with open(out / "sites.csv") as f:
        rows = list(csv.DictReader(f))
    return (np.array([[float(r["x"]), float(r["y"])] for r in rows]).reshape(-1, 2),
            np.array([float(r["size"]) for r in rows]))


def ground(pattern: str, rng) -> np.ndarray:
    """(N, 2) returns over 32 m x 30 m: ``random`` 16 per m^2, or ``lines``: scan lines 1.3 m
    apart with a return every 0.4 m along them (about 2 per m^2, as the Autzen tile)."""
    if pattern == "random":
        return rng.uniform((0.0, 0.0), (32.0, 30.0), (32 * 30 * 16, 2))
    x, y = np.meshgrid(np.arange(0.2, 32.0, 1.3), np.arange(0.1, 30.0, 0.4))
    return np.column_stack((x.ravel(), y.ravel())) + rng.normal(0, 0.03, (x.size, 2))


def patch_cloud(pattern: str, hole: bool, seed: int = 0) -> tuple[np.ndarray, float]:
    """A flat clear patch (CLEAR_X, y 8..22) beside a region HOLE_X that is either a hole
    with no returns or more flat ground; rough clutter (0.3-1.5 m) everywhere else. Returns
    the cloud (N, 4: x, y, z, class) and the x of the last return before the hole."""
    rng = np.random.default_rng(seed)
    xy = ground(pattern, rng)
    x, y = xy[:, 0], xy[:, 1]
    rows = (y > 8.0) & (y < 22.0)
    flat = rows & (x >= CLEAR_X[0]) & (x < HOLE_X[1])
    z = np.where(flat, 0.0, rng.uniform(0.3, 1.5, len(x))) + rng.normal(0, 0.01, len(x))
    in_hole = rows & (x >= HOLE_X[0]) & (x < HOLE_X[1])
    keep = ~in_hole if hole else np.ones(len(x), dtype=bool)
    last = float(x[rows & (x < HOLE_X[0])].max())
    cloud = np.column_stack((xy, z, np.full(len(x), 2.0)))[keep]
    return cloud, last


@pytest.mark.parametrize("pattern", ["random", "lines"])
def test_a_clear_patch_beside_a_hole_has_no_site_whose_ring_reaches_over_it(tmp_path,
                                                                            pattern):
    spacing = 0.25 if pattern == "random" else float(np.sqrt(1.3 * 0.4))
    filled, _ = patch_cloud(pattern, hole=False)
    np.save(tmp_path / "filled.npy", filled)
    assert lander("--lidar", tmp_path / "filled.npy", "--out", tmp_path / "filled") == 0
    centres, size = read_sites(tmp_path / "filled")
    # The filled ground holds a site whose ring lies over the hole's place.
    assert (centres[:, 0] + size + CLEARANCE > HOLE_X[0] + 1.0).any()
    with_hole, last = patch_cloud(pattern, hole=True)
    np.save(tmp_path / "hole.npy", with_hole)
    assert lander("--lidar", tmp_path / "hole.npy", "--out", tmp_path / "hole") == 0
    centres, size = read_sites(tmp_path / "hole")
    # No ring reaches beyond the last returns by more than what they speak for (about one
    # point spacing): the hole is unknown ground, not clear ground.
    reach = centres[:, 0] + size + CLEARANCE
    assert (reach <= last + 1.25 * spacing).all(), reach - last
    # and the independent judge agrees.
    judge = Judge(with_hole[:, :3], with_hole[:, 3].astype(int),
                  JudgeRules.from_settings(LidarPcaSettings()))
    safe, why = judge.judge(centres, size)
    assert safe.all(), why


def test_the_hole_is_taken_as_clear_without_the_rule(tmp_path):
    """The same cloud with --paper (no checks beyond the paper's, the coverage rule among
    them): a site's ring lies over the hole, and the judge calls it not covered."""
    with_hole, last = patch_cloud("random", hole=True)
    np.save(tmp_path / "hole.npy", with_hole)
    assert lander("--lidar", tmp_path / "hole.npy", "--paper", "--out", tmp_path / "p") == 0
    centres, size = read_sites(tmp_path / "p")
    over = centres[:, 0] + size + CLEARANCE > last + 1.0
    assert over.any()
    judge = Judge(with_hole[:, :3], with_hole[:, 3].astype(int),
                  JudgeRules.from_settings(LidarPcaSettings()))
    _, why = judge.judge(centres[over], size[over])
    assert set(why) <= {"disc not covered", "ring not covered"} and why, why


def test_a_sparse_complete_scan_counts_as_covered(tmp_path, capsys):
    """Scan lines 1.3 m apart, a return every 0.4 m (2 per m^2): all flat ground, no holes.
    Sites are found all over it (the gaps between lines are sampling, not holes: 16 sites,
    18 without the rule, the two more with rings 1.3-2.3 m off the data); only rings near
    the edge of the data are cut, to about one point spacing (0.72 m) beyond it."""
    rng = np.random.default_rng(1)
    xy = ground("lines", rng)
    z = rng.normal(0, 0.01, len(xy))
    write_las(tmp_path / "c.las", np.column_stack((xy, z)), np.full(len(xy), 2))
    assert lander("--lidar", tmp_path / "c.las", "--out", tmp_path / "o") == 0
    centres, size = read_sites(tmp_path / "o")
    assert len(centres) >= 12
    inner = np.minimum(centres - xy.min(axis=0), xy.max(axis=0) - centres).min(axis=1)
    assert (inner - size - CLEARANCE > -1.25 * np.sqrt(1.3 * 0.4)).all()
    assert (size[inner > 6.0] == 3.0).sum() >= 6  # the middle holds full-size sites
