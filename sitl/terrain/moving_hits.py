"""Where sensor rays meet the moving obstacles: exact ray / cylinder and ray / box tests.

A person is a vertical cylinder, a vehicle a box turned to its heading; both stand on the
ground under their centre (:class:`sitl.terrain.moving.ObstacleSnapshot`). The sensors cast
their rays on the terrain as before and then take, per ray, the nearer of the terrain's hit
and the obstacles' (:func:`nearer`), so nothing of the terrain's ray march changes and a
world without moving obstacles costs nothing.

Rays are handled per obstacle (there are few), vectorised over the rays; the camera only
tests the pixels inside each obstacle's projected bounding box (:func:`pinhole_hits`).
"""

from __future__ import annotations

import numpy as np

from sitl.terrain.moving import PERSON, ObstacleSnapshot


def ray_hits(snapshot: ObstacleSnapshot, origin, dx, dy, dz, t_max: float = np.inf,
             only=None) -> tuple[np.ndarray, np.ndarray]:
    """First hit of rays ``origin + t (dx, dy, dz)`` on any obstacle.

    Args:
        snapshot: the obstacles at the instant of the rays.
        origin: (3,) ENU m.
        dx, dy, dz: ray direction components, arrays of one shape (any length).
        t_max: hits beyond it do not count.
        only: indices of the obstacles to test (default all).

    Returns:
        t: ray parameter of the first hit (float64, NaN: none), the rays' shape;
        index: int16 obstacle index of that hit (-1: none).
    """
    ox, oy, oz = (float(v) for v in origin)
    dx, dy, dz = (np.asarray(a, dtype=np.float64) for a in (dx, dy, dz))
    best = np.full(dx.shape, np.inf)
    index = np.full(dx.shape, -1, dtype=np.int16)
    if only is None:  # the obstacles a ray can reach before t_max
        horizontal = float(np.sqrt(np.max(dx * dx + dy * dy))) if dx.size else 0.0
        gap = np.hypot(snapshot.x - ox, snapshot.y - oy) - snapshot.reach
        only = np.flatnonzero(gap <= t_max * horizontal) if np.isfinite(t_max) else range(
            len(snapshot.x))
    for k in only:
        c, s = np.cos(snapshot.heading[k]), np.sin(snapshot.heading[k])
        px, py = ox - snapshot.x[k], oy - snapshot.y[k]
        # the origin and the directions in the obstacle's frame (u along its heading)
        pu, pv = c * px + s * py, -s * px + c * py
        du, dv = c * dx + s * dy, -s * dx + c * dy
        with np.errstate(divide="ignore", invalid="ignore"):
            near, far = _slab(oz, dz, snapshot.base[k], snapshot.top[k])
            if snapshot.kind[k] == PERSON:
                a = du * du + dv * dv
                b = pu * du + pv * dv
                cc = pu * pu + pv * pv - snapshot.half_length[k] ** 2
                root = np.sqrt(b * b - a * cc)
                vertical = a < 1e-18  # straight down or up: inside the disc or never
                enter = np.where(vertical, np.where(cc <= 0, -np.inf, np.nan), (-b - root) / a)
                leave = np.where(vertical, np.where(cc <= 0, np.inf, np.nan), (-b + root) / a)
            else:
                enter, leave = _slab(pu, du, -snapshot.half_length[k], snapshot.half_length[k])
                e2, l2 = _slab(pv, dv, -snapshot.half_width[k], snapshot.half_width[k])
                enter, leave = np.maximum(enter, e2), np.minimum(leave, l2)
            near = np.maximum(near, enter)  # NaN (a miss) stays NaN
            far = np.minimum(far, leave)
        t = np.maximum(near, 0.0)
        hit = (near <= far) & (far >= 0) & (t <= t_max) & (t < best)
        best = np.where(hit, t, best)
        index[hit] = k
    return np.where(index >= 0, best, np.nan), index


def _slab(o: float, d: np.ndarray, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Parameters where ``o + t d`` enters and leaves [lo, hi] (-inf, inf when the ray runs
    parallel inside; NaN when parallel outside)."""
    t1 = (lo - o) / d
    t2 = (hi - o) / d
    parallel = d == 0
    inside = lo <= o <= hi
    enter = np.where(parallel, -np.inf if inside else np.nan, np.minimum(t1, t2))
    leave = np.where(parallel, np.inf if inside else np.nan, np.maximum(t1, t2))
    return enter, leave


def pinhole_hits(snapshot: ObstacleSnapshot, position, rotation, fx: float, fy: float,
                 cx: float, cy: float, width: int, height: int,
                 t_max: float = np.inf) -> tuple[np.ndarray, np.ndarray] | None:
    """The obstacles in a pinhole camera's image: (depth along the optical axis, float32
    NaN where none; int16 obstacle index, -1 where none), each (height, width); None when
    no obstacle is in view. ``rotation`` maps camera axes (x right, y down, z optical
    axis) to ENU; each obstacle is tested on the pixels of its projected bounding box."""
    p = np.asarray(position, dtype=np.float64)
    r = np.asarray(rotation, dtype=np.float64)
    reach = snapshot.reach
    # the 8 corners of every obstacle's bounding box, (n, 8, 3), in the camera frame
    sign = np.array([-1.0, 1.0])
    sx, sy, top = (a.ravel() for a in np.meshgrid(sign, sign, [0.0, 1.0], indexing="ij"))
    corners = np.stack([
        snapshot.x[:, None] + sx * reach[:, None],
        snapshot.y[:, None] + sy * reach[:, None],
        snapshot.base[:, None] + top * snapshot.height[:, None],
    ], axis=-1)
    cam = (corners - p) @ r
    zc = cam[..., 2]
    front = np.all(zc > 1e-6, axis=1)
    straddles = ~front & np.any(zc > 1e-6, axis=1)  # test every pixel
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(front[:, None], fx * cam[..., 0] / zc + cx, 0.0)
        v = np.where(front[:, None], fy * cam[..., 1] / zc + cy, 0.0)
    u0 = np.where(front, np.clip(np.floor(u.min(axis=1)), 0, width), 0).astype(int)
    u1 = np.where(front, np.clip(np.ceil(u.max(axis=1)) + 1, 0, width), width).astype(int)
    v0 = np.where(front, np.clip(np.floor(v.min(axis=1)), 0, height), 0).astype(int)
    v1 = np.where(front, np.clip(np.ceil(v.max(axis=1)) + 1, 0, height), height).astype(int)
    visible = (front & (zc.min(axis=1) <= t_max) | straddles) & (u0 < u1) & (v0 < v1)
    depth = None
    index = None
    for k in np.flatnonzero(visible):
        u0k, u1k, v0k, v1k = u0[k], u1[k], v0[k], v1[k]
        vv, uu = np.mgrid[v0k:v1k, u0k:u1k]
        xc, yc = (uu - cx) / fx, (vv - cy) / fy
        # directions with unit optical-axis component: the ray parameter is the depth
        dirs = [r[i, 0] * xc + r[i, 1] * yc + r[i, 2] for i in range(3)]
        t, _ = ray_hits(snapshot, p, *dirs, t_max=t_max, only=(k,))
        found = np.isfinite(t)
        if not found.any():
            continue
        if depth is None:
            depth = np.full((height, width), np.nan, dtype=np.float32)
            index = np.full((height, width), -1, dtype=np.int16)
        window = depth[v0k:v1k, u0k:u1k]
        closer = found & ~(window <= t)  # nearer than an earlier obstacle, or the first
        window[closer] = t[closer]
        index[v0k:v1k, u0k:u1k][closer] = k
    return None if depth is None else (depth, index)


def nearer(terrain_t: np.ndarray, obstacle_t: np.ndarray, obstacle_index: np.ndarray):
    """Per ray, the nearer of the terrain's hit and an obstacle's (NaN: no hit), and the
    obstacle index where the obstacle is the nearer (-1 elsewhere). The terrain's array is
    updated in place and returned."""
    closer = np.isfinite(obstacle_t) & ~(terrain_t < obstacle_t)
    terrain_t[closer] = obstacle_t[closer]
    return terrain_t, np.where(closer, obstacle_index, -1).astype(np.int16)


def see_moving(snapshot: ObstacleSnapshot, position, rotation, camera, depth: np.ndarray,
               t_max: float):
    """Put the obstacles of ``snapshot`` into a nadir camera's terrain ``depth`` image (in
    place: the nearer of both per pixel) and return (snapshot, per-pixel obstacle index),
    or None when none is in view. ``camera`` has ``fx, fy, cx, cy`` and its settings'
    ``width, height``."""
    s = camera.settings
    seen = pinhole_hits(snapshot, position, rotation, camera.fx, camera.fy, camera.cx,
                        camera.cy, s.width, s.height, t_max)
    if seen is None:
        return None
    _, index = nearer(depth, *seen)
    return (snapshot, index) if (index >= 0).any() else None


def obstacle_below(moving, position, t: float) -> float:
    """Distance (m) straight down from ``position`` (ENU) to the top of a moving obstacle
    (:class:`sitl.terrain.moving.MovingObstacles`) at time ``t``; inf when none is below."""
    x, y, z = (float(v) for v in position)
    if not moving.near(x, y):
        return np.inf
    snapshot = moving.at(t)
    under = (snapshot.footprint_distance(x, y) <= 0) & (snapshot.base < z)
    return max(float(z - snapshot.top[under].max()), 0.0) if under.any() else np.inf


def top_below(moving, position, t: float) -> float:
    """ENU z of the highest moving obstacle's top (:class:`sitl.terrain.moving.MovingObstacles`)
    under ``position`` at time ``t`` that the vehicle is above (its top at or below the
    vehicle): what its skids come to rest on; -inf when there is none. An obstacle whose
    top is above the vehicle (it drove into the vehicle) is the contact judge's, not a
    floor."""
    x, y, z = (float(v) for v in position)
    if not moving.near(x, y):
        return -np.inf
    snapshot = moving.at(t)
    top = snapshot.top
    under = (snapshot.footprint_distance(x, y) <= 0) & (top <= z + 1e-6)
    return float(top[under].max()) if under.any() else -np.inf


def obstacle_radiance(snapshot: ObstacleSnapshot, index: np.ndarray, x, y, z, footprint,
                      albedo) -> np.ndarray:
    """Shaded, textured radiance of obstacle surface points (ENU ``x, y, z`` on obstacle
    ``index``), like :meth:`sitl.terrain.albedo.AlbedoMap.radiance` of the ground: the
    obstacle's albedo, Lambertian light on the face hit (top, or side: a box's face normal,
    a cylinder's radial one) under the map's sun, and the map's grain laid in the
    obstacle's own frame, so the texture travels with it."""
    k = np.asarray(index, dtype=np.intp)
    c, s = np.cos(snapshot.heading[k]), np.sin(snapshot.heading[k])
    dx, dy = x - snapshot.x[k], y - snapshot.y[k]
    u, v = c * dx + s * dy, -s * dx + c * dy
    h = z - snapshot.base[k]
    top = h >= snapshot.height[k] - 1e-3
    person = snapshot.kind[k] == PERSON
    # side normals in the obstacle's frame: radial (person) or the nearer face's (box)
    along = np.abs(u) / snapshot.half_length[k] >= np.abs(v) / snapshot.half_width[k]
    nu = np.where(person, u, np.where(along, np.sign(u), 0.0))
    nv = np.where(person, v, np.where(along, 0.0, np.sign(v)))
    norm = np.maximum(np.hypot(nu, nv), 1e-9)
    nx, ny = (c * nu - s * nv) / norm, (s * nu + c * nv) / norm
    sun = albedo.sun.vector()
    light = np.where(top, sun[2], np.maximum(nx * sun[0] + ny * sun[1], 0.0))
    shading = albedo.sun.ambient + (1.0 - albedo.sun.ambient) * light
    # the grain in the obstacle's frame (offset per obstacle: no two look alike); on the
    # sides the height runs along the texture's second axis
    grain = albedo.texture(u + 17.0 * k, np.where(top, v, v + h) + 11.0 * k, 0.0, footprint)
    return np.maximum(snapshot.albedo[k] * shading * (1.0 + 0.6 * grain), 0.0)
