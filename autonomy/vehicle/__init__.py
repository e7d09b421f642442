"""The MAVLink vehicle driver: :class:`MavlinkVehicle` satisfies
:class:`behaviors.ports.VehiclePort` for ArduPilot Copter, PX4 and the embedded SITL.

    vehicle = connect("sim://", clock)          # or "udpin:0.0.0.0:14550", "tcp:127.0.0.1:5760"
    vehicle.poll(); handle = vehicle.takeoff(10.0)
"""

from autonomy.vehicle.commands import Handle
from autonomy.vehicle.connection import connect, signing_key_from_text
from autonomy.vehicle.driver import LinkStats, MavlinkVehicle, ModeChange
from autonomy.vehicle.settings import VehicleLinkSettings

__all__ = [
    "Handle",
    "LinkStats",
    "MavlinkVehicle",
    "ModeChange",
    "VehicleLinkSettings",
    "connect",
    "signing_key_from_text",
]
