"""Flight modes by name for the two autopilot families, and autopilot detection.

ArduPilot Copter names its modes by number in HEARTBEAT.custom_mode (pymavlink's
``mode_mapping_acm``). PX4 packs a main and a sub mode: ``custom_mode = (main << 16) |
(sub << 24)``, e.g. OFFBOARD 0x00060000, AUTO.TAKEOFF 0x02040000, AUTO.LOITER 0x03040000,
AUTO.LAND 0x06040000, POSCTL 0x00030000. :func:`resolve_mode` accepts a name of either family
and returns the equivalent mode of the autopilot actually flying.
"""

from __future__ import annotations

from dataclasses import dataclass

from pymavlink import mavutil
from pymavlink.dialects.v20 import ardupilotmega as mavlink

ARDUPILOT = "ardupilot"
PX4 = "px4"
UNKNOWN = "unknown"

_AUTOPILOTS = {
    mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA: ARDUPILOT,
    mavlink.MAV_AUTOPILOT_PX4: PX4,
}


def autopilot_name(heartbeat_autopilot: int) -> str:
    """HEARTBEAT.autopilot (MAV_AUTOPILOT) -> "ardupilot", "px4" or "unknown"."""
    return _AUTOPILOTS.get(heartbeat_autopilot, UNKNOWN)


def is_autopilot_heartbeat(autopilot: int, mav_type: int) -> bool:
    """True for a HEARTBEAT that comes from a flight controller (not a GCS, camera, ...)."""
    return autopilot != mavlink.MAV_AUTOPILOT_INVALID and mav_type not in (
        mavlink.MAV_TYPE_GCS,
        mavlink.MAV_TYPE_ONBOARD_CONTROLLER,
        mavlink.MAV_TYPE_GIMBAL,
        mavlink.MAV_TYPE_CAMERA,
        mavlink.MAV_TYPE_ADSB,
    )


# --- ArduPilot Copter -------------------------------------------------------------------
ARDUPILOT_MODES: dict[int, str] = dict(mavutil.mode_mapping_acm)
_ARDUPILOT_BY_NAME: dict[str, int] = {name: number for number, name in ARDUPILOT_MODES.items()}

# --- PX4 --------------------------------------------------------------------------------
_PX4_MAIN = {
    "MANUAL": mavutil.PX4_CUSTOM_MAIN_MODE_MANUAL,
    "ALTCTL": mavutil.PX4_CUSTOM_MAIN_MODE_ALTCTL,
    "POSCTL": mavutil.PX4_CUSTOM_MAIN_MODE_POSCTL,
    "ACRO": mavutil.PX4_CUSTOM_MAIN_MODE_ACRO,
    "OFFBOARD": mavutil.PX4_CUSTOM_MAIN_MODE_OFFBOARD,
    "STABILIZED": mavutil.PX4_CUSTOM_MAIN_MODE_STABILIZED,
    "RATTITUDE": mavutil.PX4_CUSTOM_MAIN_MODE_RATTITUDE,
}
_PX4_AUTO_SUB = {
    "AUTO.READY": mavutil.PX4_CUSTOM_SUB_MODE_AUTO_READY,
    "AUTO.TAKEOFF": mavutil.PX4_CUSTOM_SUB_MODE_AUTO_TAKEOFF,
    "AUTO.LOITER": mavutil.PX4_CUSTOM_SUB_MODE_AUTO_LOITER,
    "AUTO.MISSION": mavutil.PX4_CUSTOM_SUB_MODE_AUTO_MISSION,
    "AUTO.RTL": mavutil.PX4_CUSTOM_SUB_MODE_AUTO_RTL,
    "AUTO.LAND": mavutil.PX4_CUSTOM_SUB_MODE_AUTO_LAND,
    "AUTO.FOLLOW_TARGET": mavutil.PX4_CUSTOM_SUB_MODE_AUTO_FOLLOW_TARGET,
    "AUTO.PRECLAND": 9,
}
PX4_MODES: dict[str, tuple[int, int]] = {name: (main, 0) for name, main in _PX4_MAIN.items()}
PX4_MODES.update(
    {name: (mavutil.PX4_CUSTOM_MAIN_MODE_AUTO, sub) for name, sub in _PX4_AUTO_SUB.items()}
)


def px4_custom_mode(main: int, sub: int) -> int:
    """PX4 (main, sub) mode -> HEARTBEAT.custom_mode."""
    return (main << 16) | (sub << 24)


def px4_mode_name(custom_mode: int) -> str:
    """HEARTBEAT.custom_mode of PX4 -> mode name ("OFFBOARD", "AUTO.LAND", ...)."""
    main = (custom_mode >> 16) & 0xFF
    sub = (custom_mode >> 24) & 0xFF
    if main == mavutil.PX4_CUSTOM_MAIN_MODE_AUTO:
        for name, (m, s) in PX4_MODES.items():
            if m == main and s == sub:
                return name
        return f"AUTO.{sub}"
    for name, (m, _s) in PX4_MODES.items():
        if m == main:
            return name
    return f"PX4_{custom_mode:#010x}"


def mode_name(autopilot: str, custom_mode: int) -> str:
    """HEARTBEAT.custom_mode -> the mode's name for ``autopilot``."""
    if autopilot == PX4:
        return px4_mode_name(custom_mode)
    return ARDUPILOT_MODES.get(custom_mode, f"MODE_{custom_mode}")


# Same intent, other family's word: used so that set_mode("LAND") works on PX4 and
# set_mode("AUTO.LOITER") works on ArduPilot.
_PX4_EQUIVALENT = {
    "GUIDED": "OFFBOARD",
    "LAND": "AUTO.LAND",
    "LOITER": "AUTO.LOITER",
    "BRAKE": "AUTO.LOITER",
    "HOLD": "AUTO.LOITER",
    "RTL": "AUTO.RTL",
    "SMART_RTL": "AUTO.RTL",
    "AUTO": "AUTO.MISSION",
    "MISSION": "AUTO.MISSION",
    "TAKEOFF": "AUTO.TAKEOFF",
    "POSHOLD": "POSCTL",
    "ALT_HOLD": "ALTCTL",
    "STABILIZE": "STABILIZED",
}
_ARDUPILOT_EQUIVALENT = {
    "OFFBOARD": "GUIDED",
    "AUTO.LAND": "LAND",
    "AUTO.LOITER": "LOITER",
    "HOLD": "LOITER",
    "AUTO.RTL": "RTL",
    "AUTO.MISSION": "AUTO",
    "MISSION": "AUTO",
    "AUTO.TAKEOFF": "GUIDED",
    "TAKEOFF": "GUIDED",
    "POSCTL": "POSHOLD",
    "ALTCTL": "ALT_HOLD",
    "STABILIZED": "STABILIZE",
    "MANUAL": "STABILIZE",
}


@dataclass(frozen=True)
class ModeRequest:
    """A mode resolved for one autopilot: its name, what HEARTBEAT.custom_mode will read,
    and the MAV_CMD_DO_SET_MODE parameters (param2, param3) that request it."""

    name: str
    custom_mode: int
    param2: float
    param3: float


def resolve_mode(autopilot: str, name: str) -> ModeRequest:
    """The mode ``name`` (either family's word, case-insensitive) for ``autopilot``.

    Raises:
        KeyError: the autopilot has no such mode (message names the mode and autopilot).
    """
    key = name.strip().upper()
    if autopilot == PX4:
        key = _PX4_EQUIVALENT.get(key, key)
        if key not in PX4_MODES:
            raise KeyError(f"PX4 has no mode {name!r}")
        main, sub = PX4_MODES[key]
        return ModeRequest(key, px4_custom_mode(main, sub), float(main), float(sub))
    if autopilot == ARDUPILOT:
        key = _ARDUPILOT_EQUIVALENT.get(key, key)
        if key not in _ARDUPILOT_BY_NAME:
            raise KeyError(f"ArduPilot Copter has no mode {name!r}")
        number = _ARDUPILOT_BY_NAME[key]
        return ModeRequest(key, number, float(number), 0.0)
    raise KeyError(f"autopilot not known yet, cannot set mode {name!r}")


def guided_mode(autopilot: str) -> str:
    """The mode in which the autopilot follows external setpoints."""
    return "OFFBOARD" if autopilot == PX4 else "GUIDED"
