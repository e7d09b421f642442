"""The parameter table each personality shows a ground station, and what setting one does.

Names, types and units are the real autopilot's (ArduPilot's WPNAV_SPEED in cm/s, PX4's
MPC_XY_CRUISE in m/s, ...). A parameter that stands for something the simulator models is
bound to a :class:`~sitl.copter.settings.SitlSettings` field: reading it reads the field, and
setting it validates the new settings and applies them to the running vehicle (a value the
settings refuse leaves the parameter unchanged, and the reply says so by carrying the old
value). The others are kept so that ground stations find what they look for (FENCE_ENABLE,
ARMING_CHECK, ...); setting them stores the value.

Values cross the link as a float: ArduPilot casts integers to float (C cast), PX4 copies the
bytes of an int32 into the float (bytewise), as each declares in AUTOPILOT_VERSION.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from pydantic import ValidationError
from pymavlink.dialects.v20 import ardupilotmega as mavlink

from .settings import SitlSettings

INT8 = mavlink.MAV_PARAM_TYPE_INT8
INT16 = mavlink.MAV_PARAM_TYPE_INT16
INT32 = mavlink.MAV_PARAM_TYPE_INT32
REAL32 = mavlink.MAV_PARAM_TYPE_REAL32
_INT_RANGE = {INT8: (-(2**7), 2**7 - 1), INT16: (-(2**15), 2**15 - 1),
              INT32: (-(2**31), 2**31 - 1)}
_MAX_NAME = 16  # PARAM_VALUE.param_id holds 16 characters


@dataclass(frozen=True, slots=True)
class Param:
    """One parameter: ``field`` is the bound settings field (dotted for nested ones, e.g.
    "battery.capacity_mah") or "" for a stored value; ``scale`` is parameter units per
    settings unit (100 for cm/s against m/s); ``default`` is the stored value's default."""

    name: str
    type: int
    field: str = ""
    scale: float = 1.0
    default: float = 0.0


ARDUPILOT = (
    Param("SYSID_THISMAV", INT16, default=1),
    Param("SYSID_MYGCS", INT16, default=255),
    Param("FRAME_CLASS", INT8, default=1),
    Param("FRAME_TYPE", INT8, default=1),
    Param("ARMING_CHECK", INT32, default=1),
    Param("FENCE_ENABLE", INT8, default=0),
    # AC_Fence's defaults for Copter: max altitude, circle and polygon; RTL or land.
    Param("FENCE_TYPE", INT8, default=7),
    Param("FENCE_ACTION", INT8, default=1),
    Param("FENCE_ALT_MAX", REAL32, default=100.0),
    Param("FENCE_ALT_MIN", REAL32, default=-10.0),
    Param("FENCE_RADIUS", REAL32, default=300.0),
    Param("FENCE_MARGIN", REAL32, default=2.0),
    Param("FS_GCS_ENABLE", INT8, default=0),
    Param("AUTO_OPTIONS", INT32, default=0),
    Param("WP_YAW_BEHAVIOR", INT8, default=0),
    Param("ANGLE_MAX", INT16, default=4500),
    Param("BATT_MONITOR", INT8, default=4),
    Param("BATT_CAPACITY", INT32, "battery.capacity_mah"),
    Param("WPNAV_SPEED", REAL32, "max_horizontal_speed", 100.0),
    Param("WPNAV_SPEED_UP", REAL32, "max_climb_speed", 100.0),
    Param("WPNAV_SPEED_DN", REAL32, "max_descent_speed", 100.0),
    Param("WPNAV_ACCEL", REAL32, "max_horizontal_acceleration", 100.0),
    Param("WPNAV_ACCEL_Z", REAL32, "max_vertical_acceleration", 100.0),
    Param("WPNAV_RADIUS", REAL32, "waypoint_radius", 100.0),
    Param("LAND_SPEED", INT16, "land_speed", 100.0),
    Param("LAND_SPEED_HIGH", INT16, "land_speed_high", 100.0),
    Param("LAND_ALT_LOW", INT16, "land_alt_low", 100.0),
    Param("RTL_ALT", INT32, "rtl_altitude", 100.0),
    Param("DISARM_DELAY", INT8, "disarm_delay"),
    Param("GUID_TIMEOUT", REAL32, "guided_velocity_timeout"),
    Param("RNGFND1_TYPE", INT8, default=100),
    Param("RNGFND1_MIN_CM", INT16, "rangefinder_min", 100.0),
    Param("RNGFND1_MAX_CM", INT16, "rangefinder_max", 100.0),
)

PX4 = (
    Param("MAV_SYS_ID", INT32, default=1),
    Param("SYS_AUTOSTART", INT32, default=10040),
    Param("COM_RC_IN_MODE", INT32, default=4),
    Param("NAV_DLL_ACT", INT32, default=0),
    Param("NAV_RCL_ACT", INT32, default=2),
    Param("GF_ACTION", INT32, default=2),
    Param("GF_MAX_HOR_DIST", REAL32, default=0.0),
    Param("GF_MAX_VER_DIST", REAL32, default=0.0),
    Param("MIS_TAKEOFF_ALT", REAL32, "px4_takeoff_altitude"),
    Param("MPC_XY_CRUISE", REAL32, "max_horizontal_speed"),
    Param("MPC_XY_VEL_MAX", REAL32, default=12.0),
    Param("MPC_Z_VEL_MAX_UP", REAL32, "max_climb_speed"),
    Param("MPC_Z_VEL_MAX_DN", REAL32, "max_descent_speed"),
    Param("MPC_ACC_HOR", REAL32, "max_horizontal_acceleration"),
    Param("MPC_ACC_UP_MAX", REAL32, "max_vertical_acceleration"),
    Param("MPC_LAND_SPEED", REAL32, "px4_land_speed"),
    Param("MPC_TKO_SPEED", REAL32, default=1.5),
    Param("NAV_ACC_RAD", REAL32, "waypoint_radius"),
    Param("RTL_RETURN_ALT", REAL32, "rtl_altitude"),
    Param("COM_OF_LOSS_T", REAL32, "offboard_loss_timeout"),
    Param("COM_DISARM_LAND", REAL32, "px4_land_disarm_delay"),
    Param("COM_DISARM_PRFLT", REAL32, "disarm_delay"),
    Param("BAT1_CAPACITY", REAL32, "battery.capacity_mah"),
)

TABLES = {"ardupilot": ARDUPILOT, "px4": PX4}


def _get(settings: SitlSettings, field: str) -> float:
    value = settings
    for part in field.split("."):
        value = getattr(value, part)
    return float(value)


def _with(settings: SitlSettings, field: str, value: float) -> SitlSettings:
    """A validated copy of ``settings`` with ``field`` (dotted) set to ``value``."""
    data = settings.model_dump()
    node = data
    parts = field.split(".")
    for part in parts[:-1]:
        node = node[part]
    node[parts[-1]] = value
    return SitlSettings.model_validate(data)


class ParameterTable:
    """The parameters of one personality, bound to an autopilot's settings.

    Args:
        table: the :class:`Param` rows, in the order the index counts them.
        bytewise: int32 values travel as their bytes in the float (PX4); else as a cast.
        settings: a callable returning the autopilot's current settings.
        apply: called with validated new settings when a bound parameter is set.
    """

    def __init__(self, table, *, bytewise: bool, settings, apply) -> None:
        self.rows: tuple[Param, ...] = tuple(table)
        self.bytewise = bytewise
        self._settings = settings
        self._apply = apply
        self._index = {p.name: i for i, p in enumerate(self.rows)}
        self._stored = {p.name: float(p.default) for p in self.rows if not p.field}
        self.sets_refused = 0

    def __len__(self) -> int:
        return len(self.rows)

    def find(self, name: str) -> int | None:
        return self._index.get(name)

    def value(self, index: int) -> float:
        """The parameter's value in its own units."""
        p = self.rows[index]
        if p.field:
            value = _get(self._settings(), p.field) * p.scale
        else:
            value = self._stored[p.name]
        return float(round(value)) if p.type != REAL32 else value

    def encode(self, index: int) -> float:
        """The value as PARAM_VALUE.param_value carries it."""
        p = self.rows[index]
        value = self.value(index)
        if self.bytewise and p.type != REAL32:
            return struct.unpack("<f", struct.pack("<i", int(value)))[0]
        return value

    def decode(self, param_value: float, param_type: int) -> float | None:
        """The number a PARAM_SET carries, or None when it cannot be one."""
        if self.bytewise and param_type in _INT_RANGE:
            raw = struct.unpack("<i", struct.pack("<f", param_value))[0]
            return float(raw)
        return float(param_value) if math.isfinite(param_value) else None

    def set(self, index: int, value: float | None) -> bool:
        """Set parameter ``index``; False (nothing changes) when the value does not fit the
        parameter's type or the settings refuse it."""
        p = self.rows[index]
        if value is None or not math.isfinite(value):
            self.sets_refused += 1
            return False
        if p.type != REAL32:
            low, high = _INT_RANGE[p.type]
            if not low <= value <= high:
                self.sets_refused += 1
                return False
            value = float(round(value))
        if not p.field:
            self._stored[p.name] = value
            return True
        try:
            new = _with(self._settings(), p.field, value / p.scale)
        except (ValidationError, ValueError, OverflowError):
            self.sets_refused += 1
            return False
        self._apply(new)
        return True

    def stored(self, name: str) -> float:
        """A stored (unbound) parameter's value, e.g. AUTO_OPTIONS."""
        return self._stored[name]


def param_id(name: str) -> str:
    return name[:_MAX_NAME]
