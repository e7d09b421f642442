"""A kinematic multicopter and its MAVLink server (ArduPilot Copter and PX4 personalities)."""

from .settings import (
    BatterySettings,
    HomeSettings,
    MessageRates,
    SitlSettings,
    WindSettings,
)
from .simulator import Sitl, Touchdown, TruthState

__all__ = [
    "BatterySettings",
    "HomeSettings",
    "MessageRates",
    "Sitl",
    "SitlSettings",
    "Touchdown",
    "TruthState",
    "WindSettings",
]
