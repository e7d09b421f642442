"""The descent watch's eyes: greyscale frames of the nadir camera during the descent and the
optical-flow obstacle analyser of seed 004 (Algorithm 2) on consecutive ones.

:class:`DescentFlow` satisfies :class:`behaviors.ports.ObstacleWatch` for
:class:`behaviors.descent_watch.WatchedDescent`. While the behaviour watches, the runner
calls :meth:`DescentFlow.update` at ``perception.descent_flow.rate``; each call renders a
frame at the reported pose (depth by the simulator's ray casting, then
:func:`sitl.sensors.intensity.render_intensity` over the world's
:class:`~sitl.terrain.albedo.AlbedoMap`) and compares it with the previous one
(:func:`expansion_report`). Nothing is rendered while nobody watches, and a flight without
the watch builds none of this.

Why not the raw magnitudes of Algorithm 2: along a descent from 25 m to 2.5 m the flow of
flat ground grows tenfold (it is ``rho * dz / (h - dz)`` at ``rho`` pixels from the centre,
for a drop ``dz`` between frames at height ``h``), and the image's diagonal sectors hold
more corners, farther out, than the ones along its axes; no single pair of thresholds
separates a roof beside the column from the bottom of an obstacle-free descent. Here each
corner's magnitude is divided by what flat ground at the measured height would give it,
and only the excess counts (``max(0, m / expected - 1)``: 0 on the ground, ``g / (h - g)``
on a top ``g`` m high). The metric is then Algorithm 2's: excess summed over each
direction's corners (more corners and more excess, more likely an obstacle), the variance
of the m x m segment sums as the gate, O_T and V_T in these units. Sideways drift between
frames adds flow that is not the descent's: pairs taken while the camera moved more than
half as far sideways as down give no verdict, and the behaviour does not watch while it
steps.

:func:`calibrate_descent` flies the camera down an obstacle-free column and returns the
thresholds (O_T, V_T) :func:`avoidance.calibrate` derives from it (``lander flow-calibrate``
prints them).
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from autonomy.perception.descent_flow_settings import DescentFlowSettings
from avoidance import (
    DIRECTIONS,
    ObstacleReport,
    direction_sums,
    segment_sums,
    sparse_flow,
)
from behaviors.ports import ObstacleSighting, VehicleState
from sitl.sensors import DepthCamera, DepthCameraSettings, RangeFinder
from sitl.sensors.intensity import render_intensity
from sitl.terrain import Terrain
from sitl.terrain.albedo import AlbedoMap, Sun

_FAR = 10_000.0  # m: the watch camera's depth is geometric at any height (no SfM, no clip)


class DescentFlow:
    """The optical-flow watch over a simulated world (see the module's docstring).

    Args:
        terrain: the world the camera sees.
        settings: camera, exposure and thresholds.
        seed: seeds the world's grain and the camera's read noise (the flight derives it
            from the mission seed; no other part of the flight draws from it).
    """

    def __init__(self, terrain: Terrain, settings: DescentFlowSettings | None = None,
                 seed: int = 0) -> None:
        self.terrain = terrain
        self.settings = s = settings or DescentFlowSettings()
        albedo_seed, noise_seed = np.random.SeedSequence(seed).spawn(2)
        self._albedo_seed = albedo_seed
        self.rng = np.random.default_rng(noise_seed)
        camera = DepthCameraSettings(
            width=s.width, height=s.height, focal_px=s.focal_px, noise=False,
            stereo_below=_FAR, sfm_above=_FAR, stereo_max_range=_FAR, max_depth=_FAR,
        )
        self.camera = DepthCamera(terrain, camera, rangefinder=RangeFinder(terrain, rng=self.rng),
                                  rng=self.rng)
        self._albedo: AlbedoMap | None = None
        self.on = False
        self._previous: np.ndarray | None = None
        self._latest: ObstacleSighting | None = None
        self._events: list[dict[str, Any]] = []
        self.counters: Counter[str] = Counter()

    @property
    def albedo(self) -> AlbedoMap:
        """The world's albedo map (built on first use: seconds for a large world)."""
        if self._albedo is None:
            i = self.settings.intensity
            self._albedo = AlbedoMap(
                self.terrain, np.random.default_rng(self._albedo_seed),
                Sun(i.sun_azimuth, i.sun_elevation, i.ambient),
            )
        return self._albedo

    # ObstacleWatch ------------------------------------------------------------------
    def watch(self, on: bool) -> None:
        if on and not self.on:
            self.counters["watches"] += 1
        self.on = bool(on)
        self._previous = None
        self._latest = None

    def latest(self) -> ObstacleSighting | None:
        return self._latest

    # runner side --------------------------------------------------------------------
    def capture(self, position, yaw: float, now: float) -> tuple[np.ndarray, float] | None:
        """The greyscale frame seen from ``position`` (ENU m) with heading ``yaw`` (rad)
        and the height above what lies straight below (the median depth of the central
        tenth of the image, as a depth camera measures it), or None when the camera cannot
        render there (e.g. under ground)."""
        # agl 0: the watch camera always takes the geometric ("stereo") depth path.
        rendered = self.camera.render(position, yaw, now, agl=0.0)
        if rendered is None:
            return None
        h, w = rendered.depth.shape
        centre = rendered.depth[h * 9 // 20 : h * 11 // 20 + 1, w * 9 // 20 : w * 11 // 20 + 1]
        if not np.isfinite(centre).any():
            return None
        frame = render_intensity(rendered, self.albedo, self.rng, self.settings.intensity)
        return frame, float(np.nanmedian(centre))

    def update(self, state: VehicleState, now: float) -> None:
        """While watching: render a frame at the reported pose and analyse it against the
        previous one; the verdict becomes :meth:`latest`, an obstacle also an event."""
        if not self.on or state.position is None:
            return
        shot = self.capture(state.position, state.yaw, now)
        self.counters["frames"] += 1
        if shot is None:
            self._previous = None
            return
        here = tuple(float(v) for v in state.position)
        previous, self._previous = self._previous, (shot[0], shot[1], here)
        if previous is None:
            return
        before = previous[2]
        drop = before[2] - here[2]
        if np.hypot(here[0] - before[0], here[1] - before[1]) > 0.5 * max(drop, 0.0):
            self.counters["sideways"] += 1  # moving more sideways than down: not a descent
            return
        report = expansion_report(previous[0], shot[0], previous[1], drop, self.settings)
        if report is None:
            return
        self.counters["pairs"] += 1
        flagged = tuple(d for d, f in zip(DIRECTIONS, report.flagged, strict=True) if f)
        self._latest = ObstacleSighting(
            time=float(now), obstacle=report.obstacle,
            away=(float(report.away[0]), float(report.away[1])), yaw=float(state.yaw),
            directions=flagged,
        )
        if report.obstacle:
            self.counters["obstacles"] += 1
            self._events.append({
                "event": "descent_obstacle", "directions": list(flagged),
                "position": [round(float(v), 2) for v in state.position],
                "sums": [round(float(v), 1) for v in report.directions],
                "variance": round(report.variance, 1), "corners": int(len(report.points)),
            })

    def drain_events(self) -> list[dict[str, Any]]:
        events, self._events = self._events, []
        return events


def expansion_report(
    previous: np.ndarray,
    current: np.ndarray,
    height: float,
    drop: float,
    settings: DescentFlowSettings,
) -> ObstacleReport | None:
    """Algorithm 2 on the excess expansion between two frames (see the module's docstring).

    Args:
        previous, current: consecutive greyscale frames of the nadir camera.
        height: m above what lay straight below at ``previous``.
        drop: m the camera descended between them.

    Returns:
        the report (``directions`` and ``segments`` in excess expansion), or None when the
        camera did not descend at least ``settings.min_drop`` (no verdict).
    """
    if not (drop >= settings.min_drop and height > drop):
        return None
    s = settings.flow()
    points, flow = sparse_flow(previous, current, s)
    shape = np.asarray(previous).shape
    rows, cols = shape
    radius = np.hypot(points[:, 0] - (cols - 1) / 2.0, points[:, 1] - (rows - 1) / 2.0)
    inner = settings.centre_radius * np.hypot(cols, rows) / 2.0
    expected = np.maximum(radius, max(inner, 1.0)) * drop / (height - drop)
    excess = np.maximum(np.hypot(flow[:, 0], flow[:, 1]) / expected - 1.0, 0.0)
    excess[radius <= inner] = 0.0  # straight below: no direction, and too little flow
    directions = direction_sums(points, excess, shape, settings.centre_radius)
    segments = segment_sums(points, excess, shape, settings.segments)
    variance = float(segments.var())
    flagged = (directions > settings.obstacle_threshold) & (
        variance > settings.variance_threshold
    )
    return ObstacleReport(points, flow, directions, segments, variance, flagged)


def calibrate_descent(
    terrain: Terrain,
    x: float,
    y: float,
    *,
    settings: DescentFlowSettings | None = None,
    top: float = 25.0,
    bottom: float = 2.5,
    speed: float = 1.5,
    yaw: float = 0.0,
    seed: int = 0,
    margin: float = 1.25,
) -> tuple[float, float, int]:
    """O_T and V_T for ``settings``' camera and rate from a straight descent over (x, y).

    The camera descends from ``top`` to ``bottom`` m above the ground at (x, y) at
    ``speed`` m/s, one frame per 1 / ``settings.rate`` s; as :func:`avoidance.calibrate`
    does for the raw metric, the thresholds are the largest direction sum and segment
    variance of the frame pairs (here of excess expansion) times ``margin``. The column
    must be free of obstacles (open ground, as a landing site is).

    Returns:
        (O_T, V_T, number of frame pairs).

    Raises:
        ValueError: ``top`` not above ``bottom`` > 0, or fewer than two frames rendered.
    """
    s = settings or DescentFlowSettings()
    if not top > bottom > 0:
        raise ValueError(f"top ({top} m) must be above bottom ({bottom} m), both above 0")
    flow = DescentFlow(terrain, s, seed)
    ground = float(terrain.height(x, y))
    drop = speed / s.rate
    shots = []
    for i, h in enumerate(np.arange(top, bottom - 1e-9, -drop)):
        shot = flow.capture((x, y, ground + h), yaw, i / s.rate)
        if shot is not None:
            shots.append((shot[0], shot[1], ground + h))
    worst_sum = worst_var = 0.0
    pairs = 0
    for (a, height, za), (b, _, zb) in zip(shots[:-1], shots[1:], strict=True):
        report = expansion_report(a, b, height, za - zb, s)
        if report is None:
            continue
        pairs += 1
        worst_sum = max(worst_sum, float(report.directions.max()))
        worst_var = max(worst_var, report.variance)
    if pairs == 0:
        raise ValueError("the descent gave fewer than two frames: is the column on the world?")
    return worst_sum * margin, worst_var * margin, pairs
