"""The simulated depth camera as a perception input: conversion of rendered images into the
detectors' frames, and the plumbing shared by the site sources that run a detector on it."""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from behaviors.ports import VehicleState
from lsd.frames import DepthFrame, Intrinsics
from lsm.records import SiteObservation
from sitl.sensors import (
    DepthCamera,
    DepthCameraSettings,
    RangeFinder,
    RangeFinderSettings,
    RenderedDepth,
)
from sitl.sensors.region import GroundRegion
from sitl.terrain import Terrain


def to_depth_frame(rendered: RenderedDepth) -> DepthFrame:
    """The :class:`lsd.frames.DepthFrame` carrying ``rendered``'s image, per-pixel sigma,
    intrinsics, pose, time and source (arrays are shared, not copied)."""
    r = rendered
    return DepthFrame(
        depth=r.depth,
        sigma=r.sigma,
        intrinsics=Intrinsics(fx=r.fx, fy=r.fy, cx=r.cx, cy=r.cy, width=r.width, height=r.height),
        position=r.position,
        rotation=r.rotation,
        timestamp=r.timestamp,
        source=r.source,
        rendered=r.rendered,
    )


def depth_camera_over(
    terrain: Terrain,
    *,
    rng: np.random.Generator,
    camera: DepthCameraSettings | None = None,
    rangefinder: RangeFinderSettings | None = None,
) -> DepthCamera:
    """The depth camera over ``terrain`` with its range finder; both draw noise from ``rng``
    (settings default when None)."""
    finder = RangeFinder(terrain, rangefinder, rng=rng)
    return DepthCamera(terrain, camera, rangefinder=finder, rng=rng)


class DepthCameraSource:
    """Base of the :class:`~autonomy.perception.base.SiteSource` s that run a detector on
    the simulated depth camera.

    At every update the camera renders at the pose the autopilot reports (ENU position and
    yaw; its range-finder reading drives the SfM/stereo switch when it has one) and the
    frame goes to :meth:`detect`. Subclasses implement :meth:`detect` and may add
    :meth:`detector_events` and :meth:`detector_counters`.

    Args:
        camera: the depth camera over the world (it owns the range finder and the
            SfM/stereo source switch).
        use_reported_agl: take the range-finder AGL from the vehicle state (the autopilot's
            DISTANCE_SENSOR) when it has one, else measure it with the camera's range finder.
    """

    def __init__(self, camera: DepthCamera, *, use_reported_agl: bool = True) -> None:
        self.camera = camera
        self.use_reported_agl = use_reported_agl
        self._counters: Counter[str] = Counter()

    def detect(self, frame: DepthFrame) -> list[SiteObservation]:
        raise NotImplementedError

    def detector_events(self) -> list[dict[str, Any]]:
        return []

    def detector_counters(self) -> dict[str, int]:
        return {}

    def ground_needed(self, position) -> GroundRegion | None:
        """The ground the detector keeps points from for a frame taken at ``position``
        (the camera then renders only the pixels that can matter to it), or None: all."""
        return None

    def update(self, state: VehicleState, now: float) -> list[SiteObservation]:
        """Render a frame at the reported pose and return what the detector finds in it.

        Returns an empty list when there is no frame (no position yet, no SfM baseline,
        camera below ground); the reason is counted and reported by :meth:`drain_events`.
        """
        self._counters["updates"] += 1
        if state.position is None:
            self._counters["no_position"] += 1
            return []
        agl = state.rangefinder_agl if self.use_reported_agl else None
        rendered = self.camera.render(
            state.position, state.yaw, now, agl=agl, region=self.ground_needed(state.position)
        )
        if rendered is None:
            self._counters["no_frame"] += 1
            return []
        observations = self.detect(to_depth_frame(rendered))
        self._counters["observations"] += len(observations)
        return observations

    def drain_events(self) -> list[dict[str, Any]]:
        """Camera events (depth-source switches, skipped renders) then the detector's, since
        the last call."""
        return self.camera.drain_events() + self.detector_events()

    def counters(self) -> dict[str, int]:
        """Update counts, the camera's skip reasons (``camera_<reason>``) and the
        detector's counters."""
        out = dict(self._counters)
        out.update({f"camera_{k}": int(v) for k, v in self.camera.skipped.items()})
        out.update(self.detector_counters())
        return out
