"""The elevation-map detector (the thesis pipeline): depth frames fused into a robot-centric
2.5D map (:mod:`lsd.elevation.map`), analysed for landing sites
(:mod:`lsd.elevation.detector`), with its settings (:mod:`lsd.elevation.settings`)."""

from lsd.elevation.detector import ElevationDetector, MapAnalysis
from lsd.elevation.map import ElevationMap
from lsd.elevation.settings import DetectorSettings, ElevationMapSettings

__all__ = [
    "DetectorSettings",
    "ElevationDetector",
    "ElevationMap",
    "ElevationMapSettings",
    "MapAnalysis",
]
