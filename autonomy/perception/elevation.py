"""The elevation-map site source: the simulated depth camera feeding the elevation-map LSD.

At every perception update the depth camera of the simulated world is rendered at the pose
the autopilot reports, the image is converted to a :class:`lsd.frames.DepthFrame`, fused into
the robot-centric elevation map and the map's landing sites are returned for the Landing Site
Manager. The same wiring serves the embedded SITL and ArduPilot/PX4 SITL alike.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from autonomy.perception.camera import DepthCameraSource, depth_camera_over
from lsd.elevation.detector import ElevationDetector
from lsd.elevation.settings import DetectorSettings, ElevationMapSettings
from lsd.frames import DepthFrame
from lsm.records import SiteObservation
from sitl.sensors import DepthCamera, DepthCameraSettings, RangeFinderSettings
from sitl.sensors.region import GroundRegion
from sitl.terrain import Terrain


class ElevationMapSource(DepthCameraSource):
    """A :class:`~autonomy.perception.base.SiteSource` running the elevation-map detector
    on the simulated depth camera (see :class:`DepthCameraSource` for ``camera`` and
    ``use_reported_agl``)."""

    def __init__(
        self,
        camera: DepthCamera,
        detector: ElevationDetector,
        *,
        use_reported_agl: bool = True,
    ) -> None:
        super().__init__(camera, use_reported_agl=use_reported_agl)
        self.detector = detector
        # Render only the pixels that can put a point in the maps (False: every pixel,
        # e.g. to look at whole depth images).
        self.render_needed_only = True

    @classmethod
    def from_settings(
        cls,
        terrain: Terrain,
        *,
        rng: np.random.Generator,
        camera: DepthCameraSettings | None = None,
        rangefinder: RangeFinderSettings | None = None,
        elevation_map: ElevationMapSettings | None = None,
        detector: DetectorSettings | None = None,
        use_reported_agl: bool = True,
    ) -> ElevationMapSource:
        """Build the camera, its range finder (noise from ``rng``) and the detector over
        ``terrain``; settings default when None."""
        return cls(
            depth_camera_over(terrain, rng=rng, camera=camera, rangefinder=rangefinder),
            ElevationDetector(elevation_map, detector),
            use_reported_agl=use_reported_agl,
        )

    def detect(self, frame: DepthFrame) -> list[SiteObservation]:
        """Fuse the frame into the elevation map and return the map's sites."""
        return self.detector.process(frame)

    def ground_needed(self, position) -> GroundRegion | None:
        """The maps' ground once recentred at ``position``: pixels whose points cannot
        land there are not rendered (the detector fuses the same points)."""
        if not self.render_needed_only:
            return None
        x0, x1, y0, y1, reach, block = self.detector.ground_needed(
            float(position[0]), float(position[1])
        )
        return GroundRegion(x0, x1, y0, y1, reach=reach, block=block)

    def detector_events(self) -> list[dict[str, Any]]:
        return self.detector.drain_events()

    def detector_counters(self) -> dict[str, int]:
        return self.detector.counters()
