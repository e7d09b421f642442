"""The depth-costmap site source: the simulated depth camera feeding the costmap detector
(Mittal et al., section III-B).

At every perception update the depth camera renders at the pose the autopilot reports (its
range-finder reading drives the SfM/stereo switch when it has one); the frame's costmaps give
dense sites, which join the detector's global k-d tree list, and the clusters the frame
touched are returned as observations.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from autonomy.perception.camera import to_depth_frame
from behaviors.ports import VehicleState
from lsd.depth_costmap import DepthCostmapDetector, DepthCostmapSettings
from lsm.records import SiteObservation
from sitl.sensors import DepthCamera, DepthCameraSettings, RangeFinder, RangeFinderSettings
from sitl.terrain import Terrain


class DepthCostmapSource:
    """A :class:`~autonomy.perception.base.SiteSource` running the depth-costmap detector on
    the simulated depth camera.

    Args:
        camera: the depth camera over the world (with its range finder and source switch).
        detector: the costmap detector.
        use_reported_agl: take the range-finder AGL from the vehicle state when it has one.
    """

    def __init__(
        self,
        camera: DepthCamera,
        detector: DepthCostmapDetector,
        *,
        use_reported_agl: bool = True,
    ) -> None:
        self.camera = camera
        self.detector = detector
        self.use_reported_agl = use_reported_agl
        self._counters: Counter[str] = Counter()
        self._events: list[dict[str, Any]] = []

    @classmethod
    def from_settings(
        cls,
        terrain: Terrain,
        *,
        rng: np.random.Generator,
        camera: DepthCameraSettings | None = None,
        rangefinder: RangeFinderSettings | None = None,
        detector: DepthCostmapSettings | None = None,
        use_reported_agl: bool = True,
    ) -> DepthCostmapSource:
        """Build the camera, its range finder (noise from ``rng``) and the detector."""
        finder = RangeFinder(terrain, rangefinder, rng=rng)
        depth_camera = DepthCamera(terrain, camera, rangefinder=finder, rng=rng)
        return cls(
            depth_camera, DepthCostmapDetector(detector), use_reported_agl=use_reported_agl
        )

    def update(self, state: VehicleState, now: float) -> list[SiteObservation]:
        """Render a frame at the reported pose and return the clusters its sites touched;
        nothing when there is no frame or the frame is unusable (counted, with an event)."""
        self._counters["updates"] += 1
        if state.position is None:
            self._counters["no_position"] += 1
            return []
        agl = state.rangefinder_agl if self.use_reported_agl else None
        rendered = self.camera.render(state.position, state.yaw, now, agl=agl)
        if rendered is None:
            self._counters["no_frame"] += 1
            return []
        observations = self.detector.process(to_depth_frame(rendered))
        if self.detector.last_problem is not None:
            self._counters["frames_dropped"] += 1
            self._events.append({"event": "costmap_frame_dropped",
                                 "reason": self.detector.last_problem})
        self._counters["observations"] += len(observations)
        return observations

    def drain_events(self) -> list[dict[str, Any]]:
        """Camera events (depth-source switches, skipped renders) then dropped frames."""
        events, self._events = self._events, []
        return self.camera.drain_events() + events

    def counters(self) -> dict[str, int]:
        """Update counts, the camera's skip reasons and the detector's counters."""
        out = dict(self._counters)
        out.update({f"camera_{k}": int(v) for k, v in self.camera.skipped.items()})
        out.update({f"costmap_{k}": int(v) for k, v in self.detector.counters.items()})
        return out
