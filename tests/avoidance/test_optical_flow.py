"""Algorithm 2 (obstacle analyser) on frames of a simulated descent: a nadir pinhole camera
over textured ground, with and without a textured block standing beside the descent."""

from __future__ import annotations

import functools

import cv2
import numpy as np
import pytest

from avoidance import DIRECTIONS, FlowSettings, analyse, calibrate, segment_sums

SIZE = 240  # pixels
FOCAL = 200.0  # pixels
TEXEL = 0.03  # m per texture pixel


@functools.lru_cache(maxsize=8)
def _texture(seed: int, n: int = 1024) -> np.ndarray:
    """Gravel-like ground: blurred noise of three grain sizes, stretched to full contrast."""
    rng = np.random.default_rng(seed)
    layers = [cv2.GaussianBlur(rng.random((n, n)).astype(np.float32), (0, 0), sigma)
              for sigma in (1.5, 4.0, 12.0)]
    texture = sum(layer / layer.std() for layer in layers)
    return cv2.normalize(texture, None, 0.0, 255.0, cv2.NORM_MINMAX)


def _render(ground, height, block=None, block_texture=None):
    """The frame seen from ``height`` m; ``block`` = (x0, x1, y0, y1, top) in metres."""
    c = (SIZE - 1) / 2.0
    u = np.arange(SIZE, dtype=np.float32) - c
    x_pix, y_pix = np.meshgrid(u, -u)  # y up: row 0 is the top of the image

    def sample(texture, depth, texel=TEXEL):
        mx = x_pix * depth / FOCAL / texel + texture.shape[1] / 2
        my = texture.shape[0] / 2 - y_pix * depth / FOCAL / texel
        return cv2.remap(texture, mx.astype(np.float32), my.astype(np.float32),
                         cv2.INTER_LINEAR)

    frame = sample(ground, height)
    if block is not None:
        x0, x1, y0, y1, top = block
        depth = height - top
        bx, by = x_pix * depth / FOCAL, y_pix * depth / FOCAL
        on_top = (bx >= x0) & (bx <= x1) & (by >= y0) & (by <= y1)
        # The block's surface is as detailed at its distance as the ground is at its own
        # (roof gravel, leaves): its texture is finer in proportion.
        fine = sample(block_texture, depth, TEXEL / 3.0)
        frame = np.where(on_top, fine, frame)
    return np.clip(frame, 0, 255).astype(np.uint8)


def _descent(ground, start=12.0, step=0.2, frames=5, block=None, block_texture=None):
    heights = start - step * np.arange(frames)
    images = [_render(ground, h, block, block_texture) for h in heights]
    return list(zip(images[:-1], images[1:], strict=True))


@pytest.fixture(scope="module")
def thresholds():
    o_t, v_t = calibrate(_descent(_texture(1)), FlowSettings())
    return FlowSettings(obstacle_threshold=o_t, variance_threshold=v_t)


def test_flat_ground_under_another_texture_holds_no_obstacle(thresholds):
    for previous, current in _descent(_texture(2), start=11.0):
        report = analyse(previous, current, thresholds)
        assert len(report.points) > 100
        assert not report.obstacle, (report.directions, report.variance)


@pytest.mark.parametrize(
    ("block", "direction"),
    [((1.0, 3.0, 1.0, 3.0, 8.0), "upper right"), ((-3.5, -1.2, -1.2, 1.2, 8.0), "left")],
)
def test_a_block_beside_the_descent_is_flagged_where_it_stands(thresholds, block, direction):
    pairs = _descent(_texture(3), block=block, block_texture=_texture(4))
    report = analyse(*pairs[0], thresholds)
    assert report.obstacle
    strongest = DIRECTIONS[int(np.argmax(np.where(report.flagged, report.directions, -1)))]
    assert strongest == direction
    # Away from it: the flagged direction's opposite.
    angle = DIRECTIONS.index(direction) * np.pi / 4
    assert float(report.away @ np.array([np.cos(angle), np.sin(angle)])) < -0.7


def test_the_variance_gate_keeps_flat_ground_from_reading_as_an_obstacle(thresholds):
    """With no magnitude threshold at all, flat ground is still not an obstacle: only the
    segment variance tells an even expansion from a block (section 4.2.2)."""
    gate_only = FlowSettings(obstacle_threshold=0.0,
                             variance_threshold=thresholds.variance_threshold)
    for previous, current in _descent(_texture(2), start=11.0):
        report = analyse(previous, current, gate_only)
        assert report.directions.min() > 0.0 and not report.obstacle
    no_gate = FlowSettings(obstacle_threshold=0.0, variance_threshold=-1.0)
    assert analyse(*_descent(_texture(2))[0], no_gate).flagged.all()


def test_segments_sum_where_the_corners_are():
    points = np.array([[10.0, 10.0], [230.0, 10.0], [120.0, 120.0], [120.0, 121.0]])
    sums = segment_sums(points, np.array([1.0, 2.0, 3.0, 4.0]), (240, 240), 3)
    assert sums[0, 0] == 1.0 and sums[0, 2] == 2.0 and sums[1, 1] == 7.0 and sums.sum() == 10.0


def test_frames_that_are_not_greyscale_or_differ_in_shape_are_refused():
    a = np.zeros((50, 50), np.uint8)
    with pytest.raises(ValueError, match="greyscale"):
        analyse(np.zeros((50, 50, 3), np.uint8), a)
    with pytest.raises(ValueError, match="differ in shape"):
        analyse(a, np.zeros((40, 50), np.uint8))
    empty = analyse(a, a)  # a blank frame has no corners: nothing to flag
    assert not empty.obstacle and len(empty.points) == 0
