"""The depth-costmap site source: the simulated depth camera feeding the costmap detector
(Mittal et al., section III-B).

At every perception update the depth camera renders at the pose the autopilot reports; the
frame's costmaps give dense sites, which join the detector's global k-d tree list, and the
clusters the frame touched are returned as observations.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from autonomy.perception.camera import DepthCameraSource, depth_camera_over
from lsd.depth_costmap.detector import DepthCostmapDetector, DepthCostmapSettings
from lsd.frames import DepthFrame
from lsm.records import SiteObservation
from sitl.sensors import DepthCamera, DepthCameraSettings, RangeFinderSettings
from sitl.terrain import Terrain


class DepthCostmapSource(DepthCameraSource):
    """A :class:`~autonomy.perception.base.SiteSource` running the depth-costmap detector on
    the simulated depth camera (see :class:`DepthCameraSource` for ``camera`` and
    ``use_reported_agl``)."""

    def __init__(
        self,
        camera: DepthCamera,
        detector: DepthCostmapDetector,
        *,
        use_reported_agl: bool = True,
    ) -> None:
        super().__init__(camera, use_reported_agl=use_reported_agl)
        self.detector = detector
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
        return cls(
            depth_camera_over(terrain, rng=rng, camera=camera, rangefinder=rangefinder),
            DepthCostmapDetector(detector),
            use_reported_agl=use_reported_agl,
        )

    def detect(self, frame: DepthFrame) -> list[SiteObservation]:
        """The clusters the frame's sites touched; a frame the detector refuses is counted
        and reported as an event."""
        observations = self.detector.process(frame)
        if self.detector.last_problem is not None:
            self._counters["frames_dropped"] += 1
            self._events.append({"event": "costmap_frame_dropped",
                                 "reason": self.detector.last_problem})
        return observations

    def detector_events(self) -> list[dict[str, Any]]:
        events, self._events = self._events, []
        return events

    def detector_counters(self) -> dict[str, int]:
        return {f"costmap_{k}": int(v) for k, v in self.detector.counters.items()}
