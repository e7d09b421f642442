"""The LiDAR site source: the simulated LiDAR feeding the PCA landing-spot detector.

At every perception update the LiDAR of the simulated world scans from the pose the autopilot
reports (ENU position and yaw of the :class:`~behaviors.ports.VehicleState`); the scan is
accumulated by :class:`lsd.lidar_pca.LidarPcaDetector`, which processes the cloud once the
vehicle has travelled ``travel_distance`` or the cloud holds ``max_cloud_points`` (Loureiro
et al. 2021), or ``process_interval`` seconds have passed (hovering), and returns the spots
the cloud showed (re-detections included). Between processed clouds the registered
spots are re-graded at the current pose; :meth:`LidarPcaSource.best_spot` is the paper's
emergency output.
"""

from __future__ import annotations

from collections import Counter
from typing import Any

import numpy as np

from behaviors.ports import VehicleState
from lsd.lidar_pca.detector import LidarPcaDetector, LidarPcaSettings
from lsm.records import SiteObservation
from sitl.sensors.lidar import LidarScanner, LidarSettings
from sitl.terrain import Terrain


class LidarPcaSource:
    """A :class:`~autonomy.perception.base.SiteSource` running the LiDAR PCA detector on the
    simulated LiDAR.

    Args:
        scanner: the LiDAR over the world.
        detector: the PCA landing-spot detector (it accumulates the scans).
    """

    def __init__(self, scanner: LidarScanner, detector: LidarPcaDetector) -> None:
        self.scanner = scanner
        self.detector = detector
        self._counters: Counter[str] = Counter()
        self._events: list[dict[str, Any]] = []
        self._processed = 0

    @classmethod
    def from_settings(
        cls,
        terrain: Terrain,
        *,
        rng: np.random.Generator,
        lidar: LidarSettings | None = None,
        detector: LidarPcaSettings | None = None,
    ) -> LidarPcaSource:
        """Build the LiDAR (range noise from ``rng``) and the detector (search points from a
        generator spawned from ``rng``) over ``terrain``."""
        seeds = rng.spawn(2)
        return cls(
            LidarScanner(terrain, lidar, rng=seeds[0]),
            LidarPcaDetector(detector, rng=seeds[1]),
        )

    def update(self, state: VehicleState, now: float) -> list[SiteObservation]:
        """Scan at the reported pose and accumulate; return the spots found when the
        accumulated cloud was processed at this update (else nothing)."""
        self._counters["updates"] += 1
        if state.position is None:
            self._counters["no_position"] += 1
            return []
        position = np.asarray(state.position, dtype=np.float64)
        scan = self.scanner.scan(position, state.yaw, time=now)
        if len(scan) == 0:
            self._counters["empty_scans"] += 1
        observations = self.detector.add_scan(scan, position, now)
        processed = self.detector.counters["clouds_processed"]
        if processed != self._processed:
            self._processed = processed
            search = self.detector.last_search
            self._events.append(
                {
                    "event": "lidar_cloud_processed",
                    "search_points": 0 if search is None else len(search.seeds),
                    "accepted": 0 if search is None else search.n_accepted,
                    "spots": len(observations),
                }
            )
        self._counters["observations"] += len(observations)
        return observations

    def best_spot(self, state: VehicleState) -> SiteObservation | None:
        """The best registered spot graded at the reported position (emergency output)."""
        pos = None if state.position is None else np.asarray(state.position, dtype=np.float64)
        return self.detector.best_spot(pos)

    def drain_events(self) -> list[dict[str, Any]]:
        """One ``lidar_cloud_processed`` event per processed cloud since the last call."""
        events, self._events = self._events, []
        return events

    def counters(self) -> dict[str, int]:
        """Update counts, scans refused for a bad pose and the detector's counters."""
        out = dict(self._counters)
        out["scans_skipped"] = self.scanner.skipped
        out.update({f"lidar_{k}": int(v) for k, v in self.detector.counters.items()})
        return out
