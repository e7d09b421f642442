"""Things that move in a world: people and road vehicles walking or driving seeded paths.

Each obstacle has a footprint (a person: a vertical cylinder, 0.6 m across; a vehicle: a box
4.5 x 2 m aligned with its direction of travel), a height above the ground under its centre,
and a path: a polyline it walks at a constant speed, back and forth (or round, when the
path is closed). Its position is a pure function of the simulated time t, so every sensor
and the ground truth see the same obstacle at the same instant, and two flights with the
same seed see the same traffic.

Random paths come from their own ``numpy.random.Generator`` (a child of the world's seed,
:func:`moving_stream`), so a world with moving obstacles has exactly the static terrain of
the same world without them. Paths given in the settings are walked as given.

All arrays are per obstacle; :meth:`MovingObstacles.at` evaluates every obstacle at once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PERSON, VEHICLE = 0, 1
KINDS = ("person", "vehicle")

# Child index of the world seed's SeedSequence that draws the moving obstacles (the static
# world draws from default_rng(seed) itself, which this stream never touches).
_STREAM = 7


def moving_stream(seed: int) -> np.random.Generator:
    """The generator that places a world's moving obstacles, independent of its terrain's."""
    return np.random.default_rng(np.random.SeedSequence(seed).spawn(_STREAM + 1)[_STREAM])


@dataclass(frozen=True)
class ObstacleSnapshot:
    """Every moving obstacle at one instant.

    Attributes:
        time: simulated seconds.
        x, y: (n,) footprint centres, ENU m.
        heading: (n,) rad ENU, direction of travel (a vehicle's long axis).
        base: (n,) ENU z of the ground under each centre.
        kind: (n,) int, :data:`PERSON` or :data:`VEHICLE`.
        half_length, half_width: (n,) m; a person's are both its radius.
        height: (n,) m above ``base``.
        albedo: (n,) reflectance of each obstacle's surface (the greyscale camera).
    """

    time: float
    x: np.ndarray
    y: np.ndarray
    heading: np.ndarray
    base: np.ndarray
    kind: np.ndarray
    half_length: np.ndarray
    half_width: np.ndarray
    height: np.ndarray
    albedo: np.ndarray

    @property
    def top(self) -> np.ndarray:
        return self.base + self.height

    @property
    def reach(self) -> np.ndarray:
        """(n,) radius of each footprint's bounding circle, m."""
        return np.where(self.kind == PERSON, self.half_length,
                        np.hypot(self.half_length, self.half_width))

    def local(self, x, y) -> tuple[np.ndarray, np.ndarray]:
        """ENU points (any shape, broadcast against the (n,) obstacles on a new last axis)
        in each obstacle's frame: along its heading and to its left, m."""
        dx = np.asarray(x, dtype=np.float64)[..., None] - self.x
        dy = np.asarray(y, dtype=np.float64)[..., None] - self.y
        c, s = np.cos(self.heading), np.sin(self.heading)
        return c * dx + s * dy, -s * dx + c * dy

    def footprint_distance(self, x, y) -> np.ndarray:
        """Horizontal distance (m, >= 0) from ENU points to each obstacle's footprint:
        shape ``x.shape + (n,)``; 0 inside it."""
        u, v = self.local(x, y)
        person = self.kind == PERSON
        disc = np.maximum(np.hypot(u, v) - self.half_length, 0.0)
        box = np.hypot(np.maximum(np.abs(u) - self.half_length, 0.0),
                       np.maximum(np.abs(v) - self.half_width, 0.0))
        return np.where(person, disc, box)


class MovingObstacles:
    """People and vehicles on their paths (see the module's docstring).

    Args:
        kind: (n,) :data:`PERSON` / :data:`VEHICLE`.
        paths: n polylines, each (k_i, 2) ENU m (one point: it stands there).
        speed: (n,) m/s along the path (0: stands at its start).
        closed: (n,) bool: walk round (back to the first point) instead of back and forth.
        once: (n,) bool: walk the path once and stay at its end (default: none does).
        start: (n,) m along the path at t = 0.
        half_length, half_width, height: (n,) m (a person's half length is its radius).
        albedo: (n,) surface reflectance.
        ground: ``height(x, y)`` of the world (vectorised), for the obstacles' base.
    """

    def __init__(self, kind, paths, speed, closed, start, half_length, half_width, height,
                 albedo, ground, once=None) -> None:
        n = len(paths)
        self.once = np.zeros(n, bool) if once is None else np.asarray(once, bool).reshape(n)
        self.kind = np.asarray(kind, dtype=np.int8).reshape(n)
        self.speed = np.asarray(speed, dtype=np.float64).reshape(n)
        self.closed = np.asarray(closed, dtype=bool).reshape(n)
        self.start = np.asarray(start, dtype=np.float64).reshape(n)
        self.half_length = np.asarray(half_length, dtype=np.float64).reshape(n)
        self.half_width = np.asarray(half_width, dtype=np.float64).reshape(n)
        self.height = np.asarray(height, dtype=np.float64).reshape(n)
        self.albedo = np.asarray(albedo, dtype=np.float64).reshape(n)
        self.ground = ground
        # Padded vertex arrays (n, k, 2): a closed path repeats its first point at its end,
        # shorter paths repeat their last point (zero-length legs are never entered).
        polylines = []
        for path, loop in zip(paths, self.closed, strict=True):
            p = np.asarray(path, dtype=np.float64).reshape(-1, 2)
            polylines.append(np.vstack([p, p[:1]]) if loop and len(p) > 1 else p)
        k = max(2, max((len(p) for p in polylines), default=2))
        self.vertices = np.stack(
            [np.vstack([p, np.repeat(p[-1:], k - len(p), axis=0)]) for p in polylines]
        ) if n else np.zeros((0, k, 2))
        legs = np.diff(self.vertices, axis=1)
        self._leg_length = np.hypot(legs[..., 0], legs[..., 1])
        self._cumulative = np.concatenate(
            [np.zeros((n, 1)), np.cumsum(self._leg_length, axis=1)], axis=1)
        self.length = self._cumulative[:, -1]
        # The heading of a standing obstacle (or on a zero-length leg): its first leg's.
        first = np.argmax(self._leg_length > 0, axis=1) if n else np.zeros(0, int)
        first_leg = legs[np.arange(n), first] if n else np.zeros((0, 2))
        self._rest_heading = np.arctan2(first_leg[:, 1], first_leg[:, 0])
        self._leg_heading = np.arctan2(legs[..., 1], legs[..., 0])
        self._last: ObstacleSnapshot | None = None
        # Where each obstacle can ever be: its path's bounding box grown by its footprint's
        # reach, so most questions are answered without placing anyone.
        reach = np.where(self.kind == PERSON, self.half_length,
                         np.hypot(self.half_length, self.half_width))
        self._box = (self.vertices[..., 0].min(axis=1) - reach,
                     self.vertices[..., 0].max(axis=1) + reach,
                     self.vertices[..., 1].min(axis=1) - reach,
                     self.vertices[..., 1].max(axis=1) + reach)
        self._all = (float(self._box[0].min()), float(self._box[1].max()),
                     float(self._box[2].min()), float(self._box[3].max())) if n else (
            np.inf, -np.inf, np.inf, -np.inf)

    def __len__(self) -> int:
        return len(self.kind)

    def near(self, x: float, y: float, margin: float = 0.0) -> bool:
        """Whether any obstacle can ever come within ``margin`` m (horizontally) of
        (x, y): a cheap test before :meth:`at`."""
        if not (self._all[0] - margin <= x <= self._all[1] + margin
                and self._all[2] - margin <= y <= self._all[3] + margin):
            return False  # beyond every path (plain floats: the common answer is quick)
        xmin, xmax, ymin, ymax = self._box
        return bool(np.any((x >= xmin - margin) & (x <= xmax + margin)
                           & (y >= ymin - margin) & (y <= ymax + margin)))

    def at(self, t: float) -> ObstacleSnapshot:
        """Every obstacle at simulated time ``t`` (s). The last instant asked for is kept:
        the sensors and the ground truth of one tick all ask for the same one."""
        last = self._last
        if last is not None and last.time == float(t):
            return last
        self._last = self._at(float(t))
        return self._last

    def _at(self, t: float) -> ObstacleSnapshot:
        n = len(self)
        cycle = np.where(self.closed, self.length, 2.0 * self.length)
        moving = (cycle > 0) & (self.speed > 0)
        walked = self.start + self.speed * float(t)
        s = np.where(moving, np.mod(walked, np.where(moving, cycle, 1.0)), 0.0)
        s = np.where(self.once & moving, np.minimum(walked, self.length), s)
        back = ~self.closed & (s > self.length)
        s = np.where(back, 2.0 * self.length - s, s)
        # leg index: the last leg starting at or before s (never past the final leg)
        leg = np.minimum((self._cumulative[:, 1:-1] <= s[:, None]).sum(axis=1),
                         self._leg_length.shape[1] - 1) if n else np.zeros(0, int)
        rows = np.arange(n)
        length = self._leg_length[rows, leg]
        frac = np.where(length > 0, (s - self._cumulative[rows, leg]) / np.where(
            length > 0, length, 1.0), 0.0)
        a, b = self.vertices[rows, leg], self.vertices[rows, leg + 1]
        xy = a + frac[:, None] * (b - a)
        heading = np.where(length > 0, self._leg_heading[rows, leg], self._rest_heading)
        heading = np.where(back, heading + np.pi, heading)
        base = np.asarray(self.ground(xy[:, 0], xy[:, 1]), dtype=np.float64).reshape(n)
        return ObstacleSnapshot(
            time=float(t), x=xy[:, 0], y=xy[:, 1], heading=heading, base=base,
            kind=self.kind, half_length=self.half_length, half_width=self.half_width,
            height=self.height, albedo=self.albedo,
        )

    def describe(self) -> list[dict]:
        """One dict per obstacle (kind, speed, closed, path: its points, a closed one's
        without the return to the first), for reports and events."""
        return [
            {"kind": KINDS[int(k)], "speed": float(v), "closed": bool(c),
             "path": [[round(float(a), 2), round(float(b), 2)] for a, b in p]}
            for k, v, c, p in zip(self.kind, self.speed, self.closed, self._paths(), strict=True)
        ]

    def _paths(self) -> list[np.ndarray]:
        """Each obstacle's own vertices (without the padding, nor a closed path's return to
        its first point)."""
        out = []
        for verts, legs, loop in zip(self.vertices, self._leg_length, self.closed,
                                     strict=True):
            used = np.flatnonzero(legs > 0)
            own = verts[: used[-1] + 2] if used.size else verts[:1]
            out.append(own[:-1] if loop and len(own) > 2 else own)
        return out


def build_moving(settings, extent: tuple[float, float, float, float], keep_out: float,
                 ground, rng: np.random.Generator, streets: bool = False
                 ) -> MovingObstacles | None:
    """The moving obstacles ``settings`` (:class:`sitl.terrain.settings.MovingObstaclesSettings`)
    describe in a world spanning ``extent`` (xmin, xmax, ymin, ymax): the given paths, then
    ``count`` random ones drawn from ``rng``; None when there are none. With ``streets``
    (a town's grid of streets along x and y) random vehicles drive on the roads."""
    if settings is None or (settings.count == 0 and not settings.paths):
        return None
    kind, paths, speed, closed, start = [], [], [], [], []
    once = [p.once for p in settings.paths] + [False] * settings.count
    for p in settings.paths:
        kind.append(KINDS.index(p.kind))
        paths.append(np.asarray(p.path, dtype=np.float64))
        speed.append(p.speed)
        closed.append(p.closed)
        start.append(p.start)
    for _ in range(settings.count):
        k, path, v, loop = _random_path(settings, extent, keep_out, ground, rng, streets)
        kind.append(k)
        paths.append(path)
        speed.append(v)
        closed.append(loop)
        ring = np.vstack([path, path[:1]]) if loop else path
        length = np.hypot(*np.diff(ring, axis=0).T).sum()
        start.append(rng.uniform(0.0, (1.0 if loop else 2.0) * length))  # anywhere on it
    kind = np.asarray(kind)
    person = kind == PERSON
    albedo = rng.uniform(0.08, 0.7, len(kind))  # clothing and paint, dark to bright
    return MovingObstacles(
        kind, paths, speed, closed, start,
        half_length=np.where(person, settings.person_radius, settings.vehicle_length / 2),
        half_width=np.where(person, settings.person_radius, settings.vehicle_width / 2),
        height=np.where(person, settings.person_height, settings.vehicle_height),
        albedo=albedo, ground=ground, once=once,
    )


def _random_path(settings, extent, keep_out: float, ground, rng: np.random.Generator,
                 streets: bool = False):
    """(kind, (k, 2) path, speed, closed) of one random obstacle: a start in the area, then
    ``legs`` straight legs turning by up to 90 deg (a vehicle by up to 45), their total
    length in ``path_length``, kept on the world. A path ends before it would climb a step
    (a wall, a parked car, a tree: the ground rising or falling more than ``_STEP`` between
    samples ``_STEP`` apart), starts on the ground (not on a roof) and keeps out of home's
    clearing; one that keeps less than ``_MIN_PATH`` of its length is drawn again (at most
    100 times, then it stands). With ``streets`` a vehicle starts at road level, drives
    along x or y and turns square, and never leaves its start's level by ``_KERB_STEP``
    under its whole width: it stays on the roads."""
    is_vehicle = rng.random() < settings.vehicle_fraction
    kind = VEHICLE if is_vehicle else PERSON
    speed = rng.uniform(*(settings.vehicle_speed if is_vehicle else settings.person_speed))
    loop = bool(rng.random() < settings.closed_fraction)
    xmin, xmax, ymin, ymax = extent
    margin = 5.0
    turn = np.pi / 4 if is_vehicle else np.pi / 2
    on_roads = streets and is_vehicle
    step_limit = _KERB_STEP if on_roads else _STEP
    path = None
    for _ in range(100):
        if settings.area is not None:
            cx, cy, radius = settings.area
            r = radius * np.sqrt(rng.random())
            a = rng.uniform(0, 2 * np.pi)
            x0, y0 = cx + r * np.cos(a), cy + r * np.sin(a)
        else:
            x0 = rng.uniform(xmin + margin, xmax - margin)
            y0 = rng.uniform(ymin + margin, ymax - margin)
        total = rng.uniform(*settings.path_length)
        if _raised(x0, y0, ground, _KERB_STEP / 2 if on_roads else 2 * _STEP):
            continue
        if on_roads:  # along the street grid, turning square at the crossings
            heading = np.pi / 2 * (rng.integers(0, 4) + np.cumsum(
                rng.integers(-1, 2, settings.legs)))
        else:
            heading = rng.uniform(0, 2 * np.pi) + np.cumsum(
                rng.uniform(-turn, turn, settings.legs))
        step = total / settings.legs
        xs = x0 + np.concatenate([[0.0], np.cumsum(step * np.cos(heading))])
        ys = y0 + np.concatenate([[0.0], np.cumsum(step * np.sin(heading))])
        candidate = _walkable(np.column_stack([np.clip(xs, xmin + margin, xmax - margin),
                                               np.clip(ys, ymin + margin, ymax - margin)]),
                              ground, step_limit, level=on_roads,
                              width=settings.vehicle_width)
        if candidate is None or (keep_out > 0 and not _clear_of_home(candidate, keep_out)):
            continue
        path = candidate
        if loop and np.hypot(*(path[-1] - path[0])) > _STEP:
            loop = _walkable(np.vstack([path, path[:1]]), ground, step_limit,
                             whole=True, level=on_roads,
                             width=settings.vehicle_width) is not None
        break
    if path is None:  # nowhere to walk: it stands where it would have started
        path = np.array([[x0, y0]])
    return kind, path, float(speed), loop


_STEP = 0.5  # m: a rise or drop a walker or a car does not take
_MIN_PATH = 10.0  # m: a shorter random path is drawn again
_KERB_STEP = 0.1  # m: a car on a town's roads takes no kerb (the urban world's are 0.15 m)


def _raised(x: float, y: float, ground, above: float) -> bool:
    """(x, y) stands on something (a roof, a pile; a pavement for ``above`` under the kerb
    height): more than ``above`` m over the lowest ground on rings 8 to 48 m around it (a
    roof is up to 30 m wide, the middle of a town's block 35 m from its roads)."""
    a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    r = np.array([8.0, 16.0, 32.0, 48.0])[:, None]
    ring = np.asarray(ground(x + r * np.cos(a), y + r * np.sin(a)), dtype=np.float64)
    return float(np.asarray(ground(np.array([x]), np.array([y])))[0]) > ring.min() + above


def _walkable(path: np.ndarray, ground, limit: float = _STEP, whole: bool = False,
              level: bool = False, width: float = 0.0) -> np.ndarray | None:
    """``path`` up to just before its first step of more than ``limit`` m in the ground
    (with ``level``: its first departure by more than ``limit`` from its start's height,
    anywhere across ``width``; see :func:`_random_path`), or None when that leaves less
    than ``_MIN_PATH`` m (with ``whole``: when it has any)."""
    legs = np.diff(path, axis=0)
    lengths = np.hypot(legs[:, 0], legs[:, 1])
    cumulative = np.concatenate([[0.0], np.cumsum(lengths)])
    total = cumulative[-1]
    # samples every half step, each compared with the one a step back: a step whose rise
    # is spread over a cell (bilinear ground) falls within one such pair
    d = np.arange(0.0, total + _STEP / 2, _STEP / 2)
    d[-1] = min(d[-1], total)
    xy = _along(path, cumulative, d)
    h = np.asarray(ground(xy[:, 0], xy[:, 1]), dtype=np.float64)
    if level:  # the road's level, whatever the distance, across the vehicle's width too
        leg = np.clip(np.searchsorted(cumulative, d, side="right") - 1, 0, len(legs) - 1)
        unit = legs[leg] / np.maximum(lengths[leg], 1e-12)[:, None]
        side = width / 2 * np.column_stack([-unit[:, 1], unit[:, 0]])
        across = np.max([h, *(np.asarray(ground(*(xy + s * side).T), dtype=np.float64)
                              for s in (-1.0, 1.0))], axis=0)
        # sample i is off the level: the last good one is i - 1
        steps = np.flatnonzero(np.abs(across - h[0]) > limit) - 1
    else:
        rise = np.abs(h[2:] - h[:-2]) if len(h) > 2 else np.abs(np.diff(h))
        steps = np.flatnonzero(rise > limit)  # pair (i, i + 2): sample i is the last good
    if steps.size == 0:
        return path
    if whole or steps[0] < 0:
        return None
    end = d[steps[0]]  # the last sample before the step
    if end < _MIN_PATH:
        return None
    keep = cumulative < end
    return np.vstack([path[keep], _along(path, cumulative, np.array([end]))])


def _along(path: np.ndarray, cumulative: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Points at arc lengths ``d`` along a polyline with vertex arc lengths ``cumulative``."""
    return np.column_stack([np.interp(d, cumulative, path[:, 0]),
                            np.interp(d, cumulative, path[:, 1])])


def _clear_of_home(path: np.ndarray, keep_out: float) -> bool:
    """No leg of ``path`` passes within ``keep_out`` m of home (0, 0)."""
    a, b = path[:-1], path[1:]
    ab = b - a
    denom = np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12)
    f = np.clip(-np.einsum("ij,ij->i", a, ab) / denom, 0.0, 1.0)
    nearest = a + f[:, None] * ab
    return bool(np.all(np.hypot(nearest[:, 0], nearest[:, 1]) > keep_out)) if len(ab) else (
        bool(np.hypot(*path[0]) > keep_out))
