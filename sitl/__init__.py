"""The embedded simulator: terrain worlds, sensors, a kinematic multicopter and its
MAVLink server. A separate "vehicle": it never imports :mod:`autonomy` or :mod:`behaviors`.

Quick start (lockstep, everything crossing the link as MAVLink bytes)::

    from sitl import MemoryLink, Sitl
    link = MemoryLink()
    sim = Sitl(autopilot="ardupilot")
    sim.attach(link.vehicle)
    link.gcs.write(heartbeat_bytes)   # ArduPilot talks once it has heard from you
    sim.step(0.05)
    data = link.gcs.read()
"""

from .copter import Sitl, SitlSettings, Touchdown, TruthState
from .link import LinkEndpoint, MemoryLink

__all__ = ["LinkEndpoint", "MemoryLink", "Sitl", "SitlSettings", "Touchdown", "TruthState"]
