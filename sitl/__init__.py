"""The embedded simulator: terrain worlds, sensors, a kinematic multicopter and its
MAVLink server. A separate "vehicle": it never imports :mod:`autonomy` or :mod:`behaviors`.

Quick start (lockstep, everything crossing the link as MAVLink bytes)::

    from sitl import MemoryLink, Sitl
    from sitl.copter.gcs import MiniGcs

    link = MemoryLink()
    sim = Sitl(autopilot="ardupilot")     # or "px4"; terrain=any object with height(x, y)
    sim.attach(link.vehicle)
    gcs = MiniGcs(link.gcs)               # a bare pymavlink client (the driver goes here)
    gcs.heartbeat()                       # ArduPilot talks once it has heard from you
    for _ in range(200):
        sim.step(0.05)                    # simulated seconds
        gcs.poll()
    print(sim.truth)
"""

from .copter import Sitl, SitlSettings, Touchdown, TruthState
from .link import LinkEndpoint, MemoryLink

__all__ = ["LinkEndpoint", "MemoryLink", "Sitl", "SitlSettings", "Touchdown", "TruthState"]
