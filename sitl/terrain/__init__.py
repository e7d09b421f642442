"""Terrain worlds of the embedded simulator and their ground-truth landing safety.

from sitl.terrain import Terrain, TerrainSettings, make_terrain
terrain = make_terrain({"kind": "mars"}, seed=7)
terrain.height(x, y)        # bilinear, vectorised
"""

from sitl.terrain.grid import Terrain
from sitl.terrain.safety import SafetySettings, is_safe, safety_map
from sitl.terrain.settings import (
    FileTerrainSettings,
    FlatTerrainSettings,
    MarsTerrainSettings,
    RubbleTerrainSettings,
    TerrainSettings,
    UrbanTerrainSettings,
    parse_terrain_settings,
)
from sitl.terrain.worlds import make_terrain

__all__ = [
    "FileTerrainSettings",
    "FlatTerrainSettings",
    "MarsTerrainSettings",
    "RubbleTerrainSettings",
    "SafetySettings",
    "Terrain",
    "TerrainSettings",
    "UrbanTerrainSettings",
    "is_safe",
    "make_terrain",
    "parse_terrain_settings",
    "safety_map",
]
