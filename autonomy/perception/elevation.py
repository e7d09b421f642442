"""The elevation-map site source: the simulated depth camera feeding the elevation-map LSD.

At every perception update the depth camera of the simulated world is rendered at the pose
the autopilot reports (ENU position and yaw from the :class:`~behaviors.ports.VehicleState`;
the autopilot's range-finder reading drives the SfM/stereo switch when it has one), the
image is converted to a :class:`lsd.frames.DepthFrame`, fused into the robot-centric
elevation map and the map's landing sites are returned for the Landing Site Manager.
The same wiring serves the embedded SITL and ArduPilot/PX4 SITL alike.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from autonomy.perception.camera import to_depth_frame
from behaviors.ports import VehicleState
from lsd.elevation import ElevationDetector
from lsd.elevation_settings import DetectorSettings, ElevationMapSettings
from lsm.records import SiteObservation
from sitl.sensors import DepthCamera, DepthCameraSettings, RangeFinder, RangeFinderSettings
from sitl.terrain import Terrain


class ElevationMapSource:
    """A :class:`~autonomy.perception.base.SiteSource` running the elevation-map detector
    on the simulated depth camera.

    Args:
        camera: the depth camera over the world (it owns the range finder and the
            SfM/stereo source switch).
        detector: the elevation-map landing-site detector.
        use_reported_agl: take the range-finder AGL from the vehicle state (the autopilot's
            DISTANCE_SENSOR) when it has one, else measure it with the camera's range
            finder.
    """

    def __init__(
        self,
        camera: DepthCamera,
        detector: ElevationDetector,
        *,
        use_reported_agl: bool = True,
    ) -> None:
        self.camera = camera
        self.detector = detector
        self.use_reported_agl = use_reported_agl
        self._counters: Counter[str] = Counter()

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
        """Build the camera, its range finder and the detector over ``terrain``.

        Args:
            terrain: the simulated world.
            rng: seeded generator for the sensor noise (shared by camera and range finder).
            camera, rangefinder: sensor settings (defaults if None).
            elevation_map, detector: detector settings (defaults if None).
            use_reported_agl: see the class.
        """
        finder = RangeFinder(terrain, rangefinder, rng=rng)
        depth_camera = DepthCamera(terrain, camera, rangefinder=finder, rng=rng)
        return cls(
            depth_camera,
            ElevationDetector(elevation_map, detector),
            use_reported_agl=use_reported_agl,
        )

    def update(self, state: VehicleState, now: float) -> list[SiteObservation]:
        """Render a frame at the reported pose, fuse it and return the sites it shows.

        Returns an empty list when there is no frame (no position yet, no SfM baseline,
        camera below ground) or the frame is unusable; the reason is counted and reported
        by :meth:`drain_events`.
        """
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
        self._counters["observations"] += len(observations)
        return observations

    def drain_events(self) -> list[dict[str, Any]]:
        """Camera events (depth-source switches, skipped renders) then detector events
        (skipped frames), since the last call."""
        return self.camera.drain_events() + self.detector.drain_events()

    def counters(self) -> dict[str, int]:
        """Update counts, the camera's skip reasons (``camera_<reason>``) and the
        detector's frame/pixel/observation counts."""
        out = dict(self._counters)
        out.update({f"camera_{k}": int(v) for k, v in self.camera.skipped.items()})
        out.update(self.detector.counters())
        return out
