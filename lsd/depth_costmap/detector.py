"""Depth-image costmap landing-site detector (Mittal, Valada, Burgard, "Vision-based
Autonomous Landing in Catastrophe-Struck Environments", section III-B).

Per frame (H x W depth image, pinhole intrinsics, camera pose):

- J_DE (eq. 1): 1 - (D^2 - min D^2) / max D^2, depth accuracy falling with depth squared.
- J_FL (eq. 2-3): Euclidean distance transform (pixels) to the Canny edges of the depth map.
  Deviation (see :func:`depth_edges`): Canny runs on the metric depth gradients with
  thresholds in metres raised to a multiple of the frame's own gradient noise, not on the
  depth scaled to 8 bit by the frame's range (which makes noisy stereo/SfM depth all
  edges). Beyond the paper, invalid pixels and the image border bound the flatness too: a
  footprint that leaves the valid image is not known to be clear.
- J_N (eq. 4-5): exp(-theta^2 / (2 theta_th^2)), theta the angle between world z and the
  surface normal from averaged 3D gradients of the back-projected points (world frame),
  averaged over a window spanning ``normal_span`` on the ground (depth-dependent smoothing,
  as the integral-image normals the paper cites), at least ``normal_window`` px.
- J_EC: distance camera -> point as the energy proxy of eq. 6; as a score it is inverted
  (1 - normalised distance) so that, like the others, higher is better.
- J (eq. 7) = c1 J_DE + c2 J_FL + c3 J_N + c4 J_EC after min-max normalising J_DE, J_FL and
  J_EC over the valid pixels. Sites: J >= threshold and J_FL (pixels) >= the vehicle radius
  projected at the pixel's depth (f r / D), and (beyond the paper) the depth edges at least
  f (r + clearance_margin) / D away, sampled on a pixel grid whose ground spacing is
  ``site_spacing`` (the paper keeps every pixel; the sampling bounds the list and the
  clustering cost while neighbouring sites still link).
- 3D positions from the pose and the footprint's mean (inverse) depth, see
  :func:`footprint_depth`; a global list keeps a site only if no listed site is
  within ``dedup_distance`` (k-d tree); single-linkage agglomerative clustering on euclidean
  distance and z difference yields the sparse sites (cluster centroids, eq. 8), kept up to
  date incrementally: a frame's new sites only join or merge clusters (single linkage), so
  only their neighbours are searched.

Observation fields: size = J_FL * D / f (metric radius of the inscribed circle); roughness =
1 - J_N (0 on level ground); uncertainty = sigma / sigma_ref when the frame carries depth
sigma, else the raw eq. 1 term (D^2 - min D^2) / max D^2; obstacle altitude = highest world z
within the footprint + margin around the site.

Longer than 500 lines: eq. 1-8 are one pipeline whose stages share array layouts and
incremental clustering state; the settings live beside it in settings.py.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np
from scipy.cluster.hierarchy import fcluster, linkage
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree
from scipy.spatial.distance import pdist

from lsd.depth_costmap.settings import CostmapWeights, DepthCostmapSettings
from lsd.frames import DepthFrame
from lsd.pointcloud import thin_by_distance
from lsm.records import SiteObservation

__all__ = [
    "CostmapWeights",
    "Costmaps",
    "DenseSites",
    "DepthCostmapDetector",
    "DepthCostmapSettings",
    "SiteList",
    "cluster_sites",
    "compute_costmaps",
    "dense_sites",
    "depth_edges",
    "footprint_depth",
    "frame_problem",
]

SOURCE = "depth_costmap"


@dataclass
class Costmaps:
    """The per-pixel maps of one frame, all (H, W).

    Attributes:
        valid: bool, depth finite and within [d_min, d_max].
        world_z: float32 world ENU height of each pixel's point (-inf where invalid, so
            maximum filters ignore it).
        depth_accuracy, flatness, steepness, energy: float32 normalised scores in [0, 1].
        flatness_px: float32 distance (pixels) to the nearest depth edge or the image border.
        clearance_px: float32 distance (pixels) to the nearest depth edge (or invalid pixel).
        decision: float32 eq. 7 score in [0, 1] (0 where invalid).
        depth_range: (min, max) valid depth, metres (eq. 1 normalisers).
        median_depth: median valid depth (m) of every 8th row and column (None when that
            sample holds no valid pixel): the scale of the normal window and site spacing.
    """

    valid: np.ndarray
    world_z: np.ndarray
    depth_accuracy: np.ndarray
    flatness: np.ndarray
    steepness: np.ndarray
    energy: np.ndarray
    flatness_px: np.ndarray
    decision: np.ndarray
    depth_range: tuple[float, float]
    clearance_px: np.ndarray | None = None
    median_depth: float | None = None


@dataclass
class DenseSites:
    """Per-frame candidate sites (K of them), parallel arrays.

    pixels (K, 2) (row, col); positions (K, 3) ENU m; score (K,) eq. 7; size, roughness,
    uncertainty, obstacle_altitude, observation_altitude (K,).
    """

    pixels: np.ndarray = field(default_factory=lambda: np.empty((0, 2), dtype=np.int64))
    positions: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    score: np.ndarray = field(default_factory=lambda: np.empty(0))
    size: np.ndarray = field(default_factory=lambda: np.empty(0))
    roughness: np.ndarray = field(default_factory=lambda: np.empty(0))
    uncertainty: np.ndarray = field(default_factory=lambda: np.empty(0))
    obstacle_altitude: np.ndarray = field(default_factory=lambda: np.empty(0))
    observation_altitude: np.ndarray = field(default_factory=lambda: np.empty(0))

    def __len__(self) -> int:
        return len(self.score)

    def take(self, index: np.ndarray) -> DenseSites:
        return DenseSites(**{k: v[index] for k, v in vars(self).items()})


def frame_problem(frame: DepthFrame) -> str | None:
    """Why a frame cannot be used (one line), or None if it can."""
    k = frame.intrinsics
    depth = np.asarray(frame.depth)
    if depth.ndim != 2 or depth.size == 0:
        return f"depth must be a non-empty 2D image, got shape {depth.shape}"
    if not all(np.isfinite(v) and v > 0 for v in (k.fx, k.fy)):
        return f"focal lengths must be positive, got fx={k.fx}, fy={k.fy}"
    if not (np.isfinite(k.cx) and np.isfinite(k.cy)):
        return "principal point must be finite"
    pos = np.asarray(frame.position, dtype=np.float64)
    rot = np.asarray(frame.rotation, dtype=np.float64)
    if pos.shape != (3,) or rot.shape != (3, 3):
        return "pose must be a (3,) position and a (3, 3) rotation"
    if not (np.isfinite(pos).all() and np.isfinite(rot).all()):
        return "pose has NaN or inf"
    return None


def _minmax(
    values: np.ndarray,
    valid: np.ndarray | None,
    *,
    invert: bool = False,
    overwrite: bool = False,
) -> np.ndarray:
    """Min-max normalise a float32 map over the valid pixels to [0, 1] (a constant map
    becomes 1), or 1 minus that with ``invert``; invalid pixels 0. ``valid`` None: every
    pixel is valid (no masked passes). ``overwrite``: the result may reuse ``values`` (a
    temporary of the caller's)."""
    mask = None if valid is None else valid.view(np.uint8)
    if valid is not None and not valid.any():
        return np.zeros(values.shape, dtype=np.float32)
    lo, hi, _, _ = cv2.minMaxLoc(values, mask=mask)
    if hi > lo:
        # Differences first: exactly 0 at the extreme, so the result stays within [0, 1].
        out = values if overwrite else None
        if invert:  # (hi - v) / (hi - lo)
            out = np.subtract(np.float32(hi), values, out=out)
        else:  # (v - lo) / (hi - lo)
            out = np.subtract(values, np.float32(lo), out=out)
        out *= np.float32(1.0 / (hi - lo))
    else:
        out = np.ones(values.shape, dtype=np.float32)
    if mask is not None:
        out *= mask
    return out


@lru_cache(maxsize=8)
def _minus_infinity(h: int, w: int) -> np.ndarray:
    """(H, W) float32 -inf (read-only, shared): the fill of invalid world heights."""
    out = np.full((h, w), -np.inf, dtype=np.float32)
    out.flags.writeable = False
    return out


@lru_cache(maxsize=8)
def _rays(fx: float, fy: float, cx: float, cy: float, w: int, h: int):
    """Normalised image coordinates xn (1, W), yn (H, 1) and the ray length factor
    |(xn, yn, 1)| (H, W) of a pinhole camera, float32 (cached per camera)."""
    xn = ((np.arange(w, dtype=np.float32) - np.float32(cx)) / np.float32(fx))[None, :]
    yn = ((np.arange(h, dtype=np.float32) - np.float32(cy)) / np.float32(fy))[:, None]
    return xn, yn, np.sqrt(1.0 + xn * xn + yn * yn)


@lru_cache(maxsize=16)
def _step_response(blur_px: int) -> float:
    """Peak |Sobel / 8| (metres per pixel) of the depth gradient across a 1 m depth step
    after the Gaussian pre-blur of radius ``blur_px``: converts ``edge_step`` into a
    gradient threshold for this filter."""
    step = np.zeros((9, 64), dtype=np.float32)
    step[:, 32:] = 1.0
    if blur_px:
        step = cv2.GaussianBlur(step, (2 * blur_px + 1, 2 * blur_px + 1), 0,
                                borderType=cv2.BORDER_REPLICATE)
    grad = cv2.Sobel(step, cv2.CV_32F, 1, 0, ksize=3, scale=0.125,
                     borderType=cv2.BORDER_REPLICATE)
    return float(np.abs(grad).max())


_FLOAT32_MAX = float(np.finfo(np.float32).max)
_GRADIENT_UNITS = 256.0  # int16 gradient units per edge_step threshold: resolves the noise
# estimate finely and saturates only 128 edge_steps up


def depth_edges(depth: np.ndarray, valid8: np.ndarray, settings: DepthCostmapSettings):
    """Canny edges of a metric depth map, (H, W) uint8 255 at edges.

    Args:
        depth: (H, W) float32 depth (m), 0 where invalid.
        valid8: (H, W) uint8, 255 where the depth is valid.
        settings: ``edge_blur_px``, ``edge_step``, ``edge_noise_factor``, ``edge_low_ratio``.

    Deviation from the paper, which runs Canny on the depth map scaled to 8 bit with fixed
    thresholds (its simulated depth is noise-free): scaled by the frame's depth range, one
    grey level is range / 255, so a few centimetres of stereo noise over a 0.5 m range (the
    2.5 m verification hover) or SfM noise at cruise makes every pixel an edge and no
    footprint fits. Here Canny runs on the metric depth gradients (Gaussian pre-blur, Sobel,
    OpenCV's Canny on the given gradients) with thresholds in metres: the high one is the
    gradient of an ``edge_step`` depth discontinuity, raised to ``edge_noise_factor`` times
    the frame's gradient noise (median absolute gradient / 0.6745 over the valid pixels,
    robust to the edges themselves). Invalid pixels count as edges (not known to be clear).
    """
    s = settings
    src = depth
    if s.edge_blur_px:
        ksize = 2 * s.edge_blur_px + 1
        src = cv2.GaussianBlur(depth, (ksize, ksize), 0, borderType=cv2.BORDER_REPLICATE)
    # int16 gradients (what Canny takes) scaled so an edge_step discontinuity reads
    # _GRADIENT_UNITS; the noise raises the thresholds, not the scale (one pass each).
    scale = _GRADIENT_UNITS / (8.0 * s.edge_step * _step_response(s.edge_blur_px))
    dx = cv2.Sobel(src, cv2.CV_16S, 1, 0, ksize=3, scale=scale, borderType=cv2.BORDER_REPLICATE)
    dy = cv2.Sobel(src, cv2.CV_16S, 0, 1, ksize=3, scale=scale, borderType=cv2.BORDER_REPLICATE)
    high = _GRADIENT_UNITS
    if s.edge_noise_factor > 0:
        sample = dx[1::4, 1::4][valid8[1::4, 1::4] > 0]
        if sample.size:
            mad = float(np.median(np.abs(sample.astype(np.float32))))
            high = max(high, s.edge_noise_factor * mad / 0.6745)
    edges = cv2.Canny(dx, dy, high * s.edge_low_ratio, high, L2gradient=True)
    edges |= cv2.bitwise_not(valid8)
    return edges


@lru_cache(maxsize=8)
def _border_distance(h: int, w: int) -> np.ndarray:
    """(H, W) float32 distance (px) of each pixel to the image border (0 on it)."""
    rows = np.minimum(np.arange(h), np.arange(h)[::-1]).astype(np.float32)
    cols = np.minimum(np.arange(w), np.arange(w)[::-1]).astype(np.float32)
    out = np.minimum(rows[:, None], cols[None, :])
    out.flags.writeable = False
    return out


def _above(x: float) -> float:
    """The float32 just above ``x``: inRange's lower bound is inclusive, d_min is not
    (the bounds are float32, as the threshold passes they replace compared them)."""
    return float(np.nextafter(np.float32(x), np.float32(np.inf)))


def _flatness(d: np.ndarray, valid: np.ndarray | None, valid8: np.ndarray,
              settings: DepthCostmapSettings):
    """J_FL (eq. 2-3): distance transform (px) to the Canny edges of the depth map ->
    (clearance_px, flatness_px, flatness), each (H, W) float32 (see :class:`Costmaps`);
    ``valid`` None when every pixel is."""
    h, w = d.shape
    edges = depth_edges(d, valid8, settings)
    clearance_px = cv2.distanceTransform(
        cv2.bitwise_not(edges), cv2.DIST_L2, cv2.DIST_MASK_5
    )
    # Beyond the paper, the image border bounds the flatness too: a footprint that leaves
    # the image is not known to be clear.
    flatness_px = cv2.min(clearance_px, _border_distance(h, w))
    return clearance_px, flatness_px, _minmax(flatness_px, valid)


def _flatness_worker() -> ThreadPoolExecutor:
    """One worker thread for the flatness branch: OpenCV and numpy release the GIL, so the
    distance transform (the largest single step) overlaps the normals and the other maps
    on a second core; frames from several callers queue on it (same results)."""
    # Per process: a forked child does not inherit the parent's thread.
    return _worker_of_process(os.getpid())


@lru_cache(maxsize=1)
def _worker_of_process(pid: int) -> ThreadPoolExecutor:
    return ThreadPoolExecutor(max_workers=1, thread_name_prefix=f"depth-costmap-{pid}")


def compute_costmaps(frame: DepthFrame, settings: DepthCostmapSettings) -> Costmaps:
    """All costmaps of one frame (see the module docstring); the frame must pass
    :func:`frame_problem`.

    Surface normals: for a pinhole camera the cross product of the 3D gradients
    dP/du x dP/dv of P = D (xn, yn, 1) is proportional to
    n_cam = (-fx D_u, -fy D_v, D + fx xn D_u + fy yn D_v), so box-averaged depth gradients
    (a box blur, then central differences) give the averaged 3D-gradient normals without building
    the point image; the world z of the normal is R[2] . n_cam.

    Threads: the flatness maps (Canny, distance transform) are computed on one worker
    thread of this process while the calling thread computes the others, so a frame takes
    about the longer of the two branches on a machine with a free core; safe to call from
    several threads at once (their flatness branches queue on the worker).
    """
    s = settings
    k = frame.intrinsics
    depth = np.asarray(frame.depth, dtype=np.float32)
    h, w = depth.shape
    xn, yn, ray_len = _rays(k.fx, k.fy, k.cx, k.cy, w, h)
    # Valid: d_min < D <= d_max (NaN fails both), one OpenCV pass; invalid depth -> 0 (a
    # masked copy: numpy's where and masked stores cost several times more).
    valid8 = cv2.inRange(depth, _above(max(s.d_min, 1e-9)), float(np.float32(s.d_max)))
    d = cv2.copyTo(depth, valid8)  # zeros where the mask is 0
    valid = valid8 > 0
    mask8 = valid.view(np.uint8)
    # Every pixel valid (the common case): the masked passes below are identities, skip them.
    some_invalid = cv2.countNonZero(valid8) < h * w
    valid_or_all = valid if some_invalid else None
    # The flatness branch (Canny, distance transform) runs beside the other maps.
    flat = _flatness_worker().submit(_flatness, d, valid_or_all, valid8, s)
    if valid_or_all is None:
        lo, hi, _, _ = cv2.minMaxLoc(d)
    elif valid.any():
        lo, hi, _, _ = cv2.minMaxLoc(d, mask=mask8)
    else:
        lo, hi = 1.0, 1.0

    # J_DE (eq. 1) min-max normalised: 1 - (D^2 - lo^2) / hi^2 is linear in D^2, so its
    # normalised form is (hi^2 - D^2) / (hi^2 - lo^2).
    if hi > lo:
        hi2 = np.float32(hi) * np.float32(hi)  # as the farthest pixel's own d * d: exact 0
        depth_accuracy = d * d
        np.subtract(hi2, depth_accuracy, out=depth_accuracy)
        depth_accuracy *= np.float32(1.0 / (hi * hi - lo * lo))
    else:
        depth_accuracy = np.ones_like(d)
    if some_invalid:
        depth_accuracy *= mask8

    # Median depth (a subsample): the depth-dependent window of the normals.
    coarse = d[::8, ::8]
    coarse = coarse[coarse > 0]
    sampled_median = float(np.median(coarse)) if coarse.size else None
    median_depth = float(hi) if sampled_median is None else sampled_median

    # J_N (eq. 4-5) from box-averaged depth gradients, the box spanning normal_span on the
    # ground (depth-dependent smoothing: stereo noise grows with depth squared while a
    # fixed pixel window shrinks on the ground as the camera descends).
    side = s.normal_window
    if s.normal_span > 0 and median_depth > 0:
        side = max(side, round(min(k.fx, k.fy) * s.normal_span / median_depth))
    side = min(side, max(min(h, w) // 4, 1))
    win = (side, side)
    # The box-averaged normals vary on the scale of the window (>= 5 px): evaluate them at
    # half resolution (2 x 2 pixel means, then a half-size box) and interpolate back, which
    # is a quarter of the arithmetic, arccos included.
    step = 2 if side >= 4 and min(h, w) >= 8 else 1
    if step > 1:
        hs, ws = (h + 1) // 2, (w + 1) // 2
        half_d = cv2.resize(d, (ws, hs), interpolation=cv2.INTER_AREA)
        hside = max(side // 2, 1)
        dm = cv2.blur(half_d, (hside, hside), borderType=cv2.BORDER_REPLICATE)
        # Half-resolution pixel j covers full pixels 2j, 2j + 1: centre 2j + 0.5.
        xs = ((np.arange(ws, dtype=np.float32) * 2 + np.float32(0.5 - k.cx)) / k.fx)[None, :]
        ys = ((np.arange(hs, dtype=np.float32) * 2 + np.float32(0.5 - k.cy)) / k.fy)[:, None]
    else:
        dm = cv2.blur(d, win, borderType=cv2.BORDER_REPLICATE)  # box average (O(1) / pixel)
        xs, ys = xn, yn
    # Central differences of the box average (per full-resolution pixel).
    half = np.float32(0.5 / step)
    du = cv2.Sobel(dm, cv2.CV_32F, 1, 0, ksize=1, scale=half, borderType=cv2.BORDER_REPLICATE)
    dv = cv2.Sobel(dm, cv2.CV_32F, 0, 1, ksize=1, scale=half, borderType=cv2.BORDER_REPLICATE)
    du *= np.float32(-k.fx)  # n_cam x
    dv *= np.float32(-k.fy)  # n_cam y
    nz = dm - du * xs - dv * ys
    rot = np.asarray(frame.rotation, dtype=np.float64)
    up = du * np.float32(rot[2, 0])
    up += dv * np.float32(rot[2, 1])
    up += nz * np.float32(rot[2, 2])
    norm = cv2.magnitude(cv2.magnitude(du, dv), nz)
    norm += np.float32(1e-30)  # no gradient at all (outside the depth): vertical, no site
    cos_t = np.abs(up)
    cos_t /= norm
    np.minimum(cos_t, np.float32(1.0), out=cos_t)
    theta = np.arccos(cos_t, out=cos_t)
    theta *= theta
    steepness = cv2.exp(theta * np.float32(-0.5 / s.theta_th**2))
    if step > 1:
        steepness = cv2.resize(steepness, (w, h), interpolation=cv2.INTER_LINEAR)
    if some_invalid:
        steepness *= mask8

    # J_EC: distance camera -> point (= depth * |(xn, yn, 1)|), inverted so near scores high.
    energy = _minmax(d * ray_len, valid_or_all, invert=True, overwrite=True)

    pos = np.asarray(frame.position, dtype=np.float64)
    # ((r20 xn + r21 yn) + r22) d + z0, in place: one full-image array, not four.
    world_z = np.add(np.float32(rot[2, 0]) * xn, np.float32(rot[2, 1]) * yn)
    world_z += np.float32(rot[2, 2])
    world_z *= d
    world_z += np.float32(pos[2])
    if some_invalid:
        cv2.copyTo(_minus_infinity(h, w), cv2.bitwise_not(valid8), world_z)

    c = s.weights
    clearance_px, flatness_px, flatness = flat.result()
    decision = cv2.addWeighted(depth_accuracy, c.depth_accuracy, flatness, c.flatness, 0.0)
    cv2.addWeighted(decision, 1.0, steepness, c.steepness, 0.0, dst=decision)
    cv2.addWeighted(decision, 1.0, energy, c.energy, 0.0, dst=decision)  # 0 where invalid
    return Costmaps(
        valid=valid,
        world_z=world_z,
        depth_accuracy=depth_accuracy,
        flatness=flatness,
        steepness=steepness,
        energy=energy,
        flatness_px=flatness_px,
        decision=decision,
        clearance_px=clearance_px,
        depth_range=(float(lo), float(hi)),
        median_depth=sampled_median,
    )


def footprint_depth(
    depth: np.ndarray, valid: np.ndarray, rows: np.ndarray, cols: np.ndarray, radius: float
) -> np.ndarray:
    """Mean valid depth (m) over the square inscribed in each site's footprint, (K,) float64.

    Args:
        depth: (H, W) depth image (m); valid: (H, W) bool, the pixels to average.
        rows, cols: (K,) site pixels; radius: footprint radius at unit depth (f r, px m),
            so the square's half side is 0.7 f r / D pixels at the site's depth D.

    Beyond the paper (which back-projects each site's own pixel): the footprint passed the
    flatness check, so it holds one surface, and its mean depth is that surface's depth at
    the centre without the per-pixel noise (exact for a plane, the window being symmetric:
    the mean is taken of the inverse depth, which is linear across the image of a plane).
    The site positions then agree to well within the clustering's z threshold.
    """
    h, w = depth.shape
    mask8 = valid.view(np.uint8)
    # Inverse depth is linear across the image of a plane (1/D = n . ray / offset), so its
    # window mean is the centre's exactly; depth itself is not (tilted views).
    all_valid = cv2.countNonZero(mask8) == mask8.size
    if all_valid:
        with np.errstate(divide="ignore", invalid="ignore"):
            inverse = np.divide(np.float32(1.0), np.asarray(depth, dtype=np.float32))
    else:
        # Invalid -> 0 -> 1/0 = inf -> 0 (threshold in place): three cheap passes, where
        # one division of the raw image, NaN and all, costs several times more.
        inverse = cv2.copyTo(np.asarray(depth, dtype=np.float32), mask8)
        with np.errstate(divide="ignore"):
            np.divide(np.float32(1.0), inverse, out=inverse)
        cv2.threshold(inverse, _FLOAT32_MAX, 0.0, cv2.THRESH_TOZERO_INV, dst=inverse)
    total = cv2.integral(inverse, sdepth=cv2.CV_64F)
    centre = np.asarray(depth)[rows, cols].astype(np.float64)
    a = np.maximum((0.7 * radius / np.maximum(centre, 1e-6)).astype(np.int64), 0)
    r0, r1 = np.maximum(rows - a, 0), np.minimum(rows + a + 1, h)
    c0, c1 = np.maximum(cols - a, 0), np.minimum(cols + a + 1, w)

    def box(table):
        return (table[r1, c1] - table[r0, c1] - table[r1, c0] + table[r0, c0]).astype(
            np.float64
        )

    # Valid pixels in each window: its area when every pixel is valid.
    n = ((r1 - r0) * (c1 - c0)).astype(np.float64) if all_valid else box(cv2.integral(mask8))
    mean_inverse = box(total) / np.maximum(n, 1)
    return np.where((n > 0) & (mean_inverse > 0), 1.0 / np.maximum(mean_inverse, 1e-12), centre)


def _block_max(values: np.ndarray, b: int) -> np.ndarray:
    """Maximum over the b x b tiles of an (H, W) image, (ceil((H - b//2) / b),
    ceil((W - b//2) / b)): tile (i, j) holds rows [i b, i b + b) and columns [j b, j b + b)
    clipped to the image, so it equals a b x b dilation (replicated border) sampled at the
    tile centres b//2 + i b, in a reshape instead of a full-image filter."""
    def along(a: np.ndarray, axis: int) -> np.ndarray:
        n = a.shape[axis]
        tiles = -(-(n - b // 2) // b)
        full = min(tiles, n // b)
        a = np.moveaxis(a, axis, 0)
        out = a[: full * b].reshape(full, b, *a.shape[1:]).max(axis=1)
        if tiles > full:  # the last tile is cut by the image edge
            out = np.concatenate((out, a[full * b :].max(axis=0, keepdims=True)))
        return np.moveaxis(out, 0, axis)

    return np.ascontiguousarray(along(along(values, 0), 1))


def dense_sites(
    frame: DepthFrame, maps: Costmaps, settings: DepthCostmapSettings
) -> DenseSites:
    """Thresholded, footprint-checked candidate sites of one frame, sampled every
    ``site_spacing`` metres on the ground (or every ``site_stride`` pixels)."""
    s = settings
    k = frame.intrinsics
    f = min(k.fx, k.fy)
    depth_full = np.asarray(frame.depth, dtype=np.float32)
    if not maps.valid.any():
        return DenseSites()
    if s.site_stride is not None:
        stride = s.site_stride
    else:
        median = maps.median_depth
        if median is None:  # maps built elsewhere, or no valid pixel in the sample
            coarse = depth_full[::8, ::8][maps.valid[::8, ::8]]
            if coarse.size == 0:
                coarse = depth_full[maps.valid]
            median = float(np.median(coarse))
        stride = max(1, int(f * s.site_spacing / median))
    while True:
        off = stride // 2
        # Only the sampled pixels are tested: every stride-th row and column.
        sub = (slice(off, None, stride), slice(off, None, stride))
        depth = depth_full[sub]
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            mask = (
                maps.valid[sub]
                & (maps.decision[sub] >= s.threshold)
                & (maps.flatness_px[sub] * depth >= np.float32(f * s.vehicle_radius))
            )
            if maps.clearance_px is not None and s.clearance_margin > 0:
                mask &= maps.clearance_px[sub] * depth >= np.float32(
                    f * (s.vehicle_radius + s.clearance_margin)
                )
        n = int(np.count_nonzero(mask))
        if n <= s.max_dense_sites:
            break
        stride = max(stride + 1, int(np.ceil(stride * np.sqrt(n / s.max_dense_sites))))
    rb, cb = np.nonzero(mask)
    if len(rb) == 0:
        return DenseSites()
    rows, cols = rb * stride + off, cb * stride + off
    d = footprint_depth(depth_full, maps.valid, rows, cols, f * s.vehicle_radius)
    xn, yn, _ = _rays(k.fx, k.fy, k.cx, k.cy, frame.depth.shape[1], frame.depth.shape[0])
    cam = np.stack((xn[0, cols] * d, yn[rows, 0] * d, d), axis=1)
    positions = cam @ np.asarray(frame.rotation, dtype=np.float64).T + np.asarray(
        frame.position, dtype=np.float64
    )

    # Obstacle altitude: highest world z within radius_px pixels of the site (the footprint +
    # margin disc projected at the frame's nearest depth: nearer things look bigger, so this
    # window covers the disc for any obstacle height). Max over b x b blocks (a small
    # dilation sampled at the block centres), then over the blocks around the site's block:
    # conservative by under a block, and cheaper than one large dilation.
    nearest = max(maps.depth_range[0], 1e-6)
    radius_px = int(np.ceil(f * (s.vehicle_radius + s.obstacle_margin) / nearest))
    valid_z = maps.world_z
    h, w = frame.depth.shape
    radius_px = min(radius_px, max(h, w))  # beyond that the window is the whole image
    b = min(2 * (radius_px // 6) + 1, 2 * ((min(h, w) - 1) // 2) + 1)
    blocks = _block_max(valid_z, b) if b > 1 else valid_z
    q = -(-radius_px // b) + (1 if b > 1 else 0)
    rect = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * q + 1, 2 * q + 1))
    zmax = cv2.dilate(np.ascontiguousarray(blocks), rect, borderType=cv2.BORDER_REPLICATE)
    bi = np.minimum(rows // b, zmax.shape[0] - 1)
    bj = np.minimum(cols // b, zmax.shape[1] - 1)
    obstacle = np.maximum(zmax[bi, bj].astype(np.float64), positions[:, 2])

    if frame.sigma is not None:
        sig = np.asarray(frame.sigma)[rows, cols].astype(np.float64)
        uncertainty = np.clip(np.nan_to_num(sig, nan=s.sigma_ref) / s.sigma_ref, 0.0, 1.0)
    else:  # the raw eq. 1 term
        lo, hi = maps.depth_range
        uncertainty = np.clip((d * d - lo * lo) / (hi * hi), 0.0, 1.0)
    cam_z = float(np.asarray(frame.position, dtype=np.float64)[2])
    return DenseSites(
        pixels=np.stack((rows, cols), axis=1),
        positions=positions,
        score=maps.decision[rows, cols].astype(np.float64),
        size=maps.flatness_px[rows, cols].astype(np.float64) * d / f,
        roughness=np.clip(1.0 - maps.steepness[rows, cols].astype(np.float64), 0.0, 1.0),
        uncertainty=uncertainty,
        obstacle_altitude=obstacle,
        observation_altitude=np.maximum(cam_z - positions[:, 2], 0.0),
    )


def cluster_sites(
    positions: np.ndarray, distance: float, dz: float, hierarchy_limit: int = 2000
) -> np.ndarray:
    """Agglomerative single-linkage clustering of sites, ``(N, 3)`` -> labels ``(N,)`` 0..C-1.

    Two sites link when their euclidean distance is <= ``distance`` and their z difference
    <= ``dz`` (metric max(d / distance, |dz| / dz), cut at 1). Up to ``hierarchy_limit`` sites
    this runs :func:`scipy.cluster.hierarchy.linkage`; above it, the connected components of
    the same link graph from a k-d tree, which is the same partition without the O(N^2)
    distance matrix.
    """
    pos = np.asarray(positions, dtype=np.float64)
    n = len(pos)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    if n == 1:
        return np.zeros(1, dtype=np.int64)
    if n <= hierarchy_limit:
        metric = np.maximum(pdist(pos) / distance, pdist(pos[:, 2:3], "cityblock") / dz)
        labels = fcluster(linkage(metric, method="single"), t=1.0, criterion="distance")
        return np.unique(labels, return_inverse=True)[1].ravel()
    pairs = cKDTree(pos).query_pairs(distance, output_type="ndarray")
    pairs = pairs[np.abs(pos[pairs[:, 0], 2] - pos[pairs[:, 1], 2]) <= dz]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    return connected_components(graph, directed=False)[1].astype(np.int64)


def _tree(positions: np.ndarray) -> cKDTree:
    """k-d tree of (N, 3) positions built for speed (sliding midpoint, no node
    compaction: about half the build time, the same query answers)."""
    return cKDTree(positions, balanced_tree=False, compact_nodes=False)


class SiteList:
    """The global list of dense sites, de-duplicated with a k-d tree.

    A site is added only if no listed site lies within ``dedup_distance``; a site that is
    already listed is refreshed instead (redetection: the lower observation altitude wins).
    """

    def __init__(self, dedup_distance: float, max_sites: int) -> None:
        self.dedup_distance = float(dedup_distance)
        self.max_sites = int(max_sites)
        self.sites = DenseSites()
        self.timestamp = np.empty(0)
        self._tree: cKDTree | None = None

    def __len__(self) -> int:
        return len(self.sites)

    @property
    def tree(self) -> cKDTree | None:
        """k-d tree over the listed positions (None while the list is empty)."""
        return self._tree

    def add(self, new: DenseSites, now: float = 0.0) -> np.ndarray:
        """Add a frame's sites; return, for each input site, its index in the list, or -1
        when it was not listed (list full)."""
        out = np.full(len(new), -1, dtype=np.int64)
        if len(new) == 0:
            return out
        r = self.dedup_distance
        fresh = np.ones(len(new), dtype=bool)
        if self._tree is not None and r > 0:
            dist, near = self._tree.query(new.positions, distance_upper_bound=r)
            seen = np.isfinite(dist)
            out[seen] = near[seen]
            fresh = ~seen
            old_alt = self.sites.observation_altitude[np.where(seen, near, 0)]
            lower = seen & (new.observation_altitude < old_alt)
            for key, arr in vars(self.sites).items():
                if key != "positions":  # the listed position stays put
                    arr[near[lower]] = getattr(new, key)[lower]
            self.timestamp[near[seen]] = now
        idx = np.flatnonzero(fresh)
        dropped = np.empty(0, dtype=np.int64)
        if r > 0 and len(idx) > 1:
            # Within the batch: greedy, best score first, so no two listed sites are within r.
            idx = idx[np.argsort(-new.score[idx], kind="stable")]
            keep = thin_by_distance(new.positions[idx], r)
            dropped, idx = idx[~keep], np.sort(idx[keep])
        idx = idx[: max(self.max_sites - len(self.sites), 0)]
        if len(idx):
            start = len(self.sites)
            self.sites = DenseSites(
                **{
                    k: np.concatenate((v, getattr(new, k)[idx]))
                    for k, v in vars(self.sites).items()
                }
            )
            self.timestamp = np.concatenate((self.timestamp, np.full(len(idx), float(now))))
            # Rebuilt every frame: the sliding-midpoint tree builds in half the time of the
            # balanced one and answers the same queries.
            self._tree = _tree(self.sites.positions)
            out[idx] = start + np.arange(len(idx))
        if len(dropped) and len(idx):
            # A dropped duplicate maps to the listed site that displaced it.
            dist, near = _tree(new.positions[idx]).query(
                new.positions[dropped], distance_upper_bound=r
            )
            found = np.isfinite(dist)
            out[dropped[found]] = out[idx[near[found]]]
        return out


class DepthCostmapDetector:
    """Stateful costmap detector: per frame costmaps -> dense sites -> global list ->
    clusters.

    :meth:`process` returns one observation per cluster that this frame's sites fell in; a
    frame that cannot be used (bad shape, non-positive focal length, NaN pose) is dropped and
    counted in :attr:`counters` with the reason in :attr:`last_problem`, never raised.
    """

    def __init__(self, settings: DepthCostmapSettings | None = None) -> None:
        self.settings = settings or DepthCostmapSettings()
        self.site_list = SiteList(self.settings.dedup_distance, self.settings.max_sites)
        self.last_maps: Costmaps | None = None
        self.last_sites = DenseSites()
        self.last_problem: str | None = None
        self.labels = np.empty(0, dtype=np.int64)
        # Cluster of each listed site, kept up to date as sites join (see add_sites).
        self._cluster = np.empty(0, dtype=np.int64)
        self.counters: dict[str, int] = {
            "frames": 0,
            "frames_dropped": 0,
            "pixels_invalid": 0,
            "dense_sites": 0,
            "sites_listed": 0,
            "sites_not_listed": 0,  # the global list was full (max_sites)
        }

    def process(self, frame: DepthFrame) -> list[SiteObservation]:
        """Detect sites in one frame; return the observations of the clusters it touched."""
        s = self.settings
        self.counters["frames"] += 1
        self.last_problem = frame_problem(frame)
        if self.last_problem is not None:
            self.counters["frames_dropped"] += 1
            return []
        maps = compute_costmaps(frame, s)
        dense = dense_sites(frame, maps, s)
        self.last_maps, self.last_sites = maps, dense
        self.counters["pixels_invalid"] += maps.valid.size - int(np.count_nonzero(maps.valid))
        return self.add_sites(dense, frame.timestamp)

    def add_sites(self, dense: DenseSites, now: float = 0.0) -> list[SiteObservation]:
        """Add one frame's dense sites to the global list and return the observations of
        the clusters they fell in (the de-duplication and clustering stage)."""
        self.counters["dense_sites"] += len(dense)
        before = len(self.site_list)
        ids = self.site_list.add(dense, now)
        self.counters["sites_listed"] += len(self.site_list) - before
        self.counters["sites_not_listed"] += int((ids < 0).sum())
        listed = ids[ids >= 0]
        self._link_new_sites(before)
        if len(listed) == 0:
            return []
        touched = np.unique(self._cluster[listed])
        # Touched cluster -> 0..T-1 by a lookup table (cluster ids are 0..C-1).
        rank = np.full(int(self._cluster.max()) + 1, -1, dtype=np.int64)
        rank[touched] = np.arange(len(touched))
        label_of_site = rank[self._cluster]
        members = np.flatnonzero(label_of_site >= 0)
        labels = label_of_site[members]
        return self._observations(members, labels, np.arange(len(touched)))

    def _link_new_sites(self, first_new: int) -> None:
        """Join the listed sites ``first_new`` onwards to the clusters.

        Single linkage only ever merges: the partition after adding sites is that of the
        old clusters plus the new sites, joined by the links (euclidean distance <=
        ``cluster_distance`` and z difference <= ``cluster_dz``) that touch a new site. So
        only the new sites' neighbours are searched (k-d tree) and the connected components
        of the small graph {old clusters, new sites} relabel the list: the same partition as
        :func:`cluster_sites` over the whole list, at a cost that grows with the frame's
        sites rather than with the list.
        """
        s = self.settings
        pos = self.site_list.sites.positions
        n_new = len(pos) - first_new
        if n_new <= 0:
            return
        old = self._cluster
        n_old_clusters = int(old.max()) + 1 if len(old) else 0
        fresh = pos[first_new:]
        pairs = _tree(fresh).sparse_distance_matrix(
            self.site_list.tree, s.cluster_distance, output_type="ndarray"
        )
        i, j = pairs["i"].astype(np.int64), pairs["j"].astype(np.int64)
        close = np.abs(fresh[i, 2] - pos[j, 2]) <= s.cluster_dz
        i, j = i[close], j[close]
        # Graph nodes: old clusters 0..C-1, then the new sites C..C+n_new-1.
        node_of_site = np.concatenate((old, n_old_clusters + np.arange(n_new)))
        n_nodes = n_old_clusters + n_new
        # CSR built directly (rows sorted, duplicates harmless): the components do not
        # depend on the order of a row's entries.
        rows = n_old_clusters + i
        order = np.argsort(rows, kind="stable")
        indptr = np.zeros(n_nodes + 1, dtype=np.int64)
        np.cumsum(np.bincount(rows, minlength=n_nodes), out=indptr[1:])
        graph = csr_matrix(
            (np.ones(len(order)), node_of_site[j][order], indptr), shape=(n_nodes, n_nodes)
        )
        component = connected_components(graph, directed=False)[1].astype(np.int64)
        self._cluster = component[node_of_site]

    def clusters(self) -> list[SiteObservation]:
        """Every cluster of the whole global list as an observation (the sparse sites);
        :attr:`labels` then holds each listed site's cluster."""
        n = len(self.site_list)
        if n == 0:
            return []
        s = self.settings
        self.labels = cluster_sites(
            self.site_list.sites.positions, s.cluster_distance, s.cluster_dz, s.hierarchy_limit
        )
        return self._observations(
            np.arange(n), self.labels, np.arange(int(self.labels.max()) + 1)
        )

    def _observations(
        self, members: np.ndarray, labels: np.ndarray, which: np.ndarray
    ) -> list[SiteObservation]:
        """Cluster centroids (eq. 8) of the listed sites ``members`` (indices) labelled
        ``labels``, for the clusters ``which``, with aggregated properties: mean roughness and
        uncertainty, the size of the member nearest the centroid, highest obstacle, lowest
        observation altitude, latest time. A centroid
        farther than ``cluster_distance`` from every member (a chained, non-convex cluster)
        is replaced by the member nearest to it, so the site stays on detected ground."""
        if len(which) == 0:
            return []
        sites = self.site_list.sites.take(members)
        stamps = self.site_list.timestamp[members]
        n = int(labels.max()) + 1
        count = np.bincount(labels, minlength=n).astype(np.float64)

        def mean(values: np.ndarray) -> np.ndarray:
            return np.bincount(labels, values, minlength=n) / count

        centre = np.stack([mean(sites.positions[:, k]) for k in range(3)], axis=1)
        gap = np.linalg.norm(sites.positions - centre[labels], axis=1)
        order = np.lexsort((gap, labels))
        nearest = order[np.unique(labels[order], return_index=True)[1]]
        far = gap[nearest] > self.settings.cluster_distance
        centre[far] = sites.positions[nearest[far]]
        obstacle = np.full(n, -np.inf)
        np.maximum.at(obstacle, labels, sites.obstacle_altitude)
        obs_alt = np.full(n, np.inf)
        np.minimum.at(obs_alt, labels, sites.observation_altitude)
        stamp = np.full(n, -np.inf)
        np.maximum.at(stamp, labels, stamps)
        rough, unc = mean(sites.roughness), mean(sites.uncertainty)
        size = sites.size[nearest]  # the inscribed circle at the member nearest the centre
        rows = zip(
            centre[which].tolist(),
            rough[which].tolist(),
            unc[which].tolist(),
            size[which].tolist(),
            np.maximum(obstacle, centre[:, 2])[which].tolist(),
            obs_alt[which].tolist(),
            stamp[which].tolist(),
            strict=True,
        )
        return [
            SiteObservation(c[0], c[1], c[2], r, u, sz, ob, alt, t, SOURCE)
            for c, r, u, sz, ob, alt, t in rows
        ]
