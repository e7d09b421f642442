"""The steps of a geofence upload and of putting the vehicle's own fence back after the
flight, as generators the driver runs as one procedure each
(:class:`autonomy.vehicle.commands.Procedure`). What each step sends and why is in
:mod:`autonomy.vehicle.fence`; the exchanges themselves (mission transfers, parameters,
commands) are the driver's, started through :class:`Exchanges` and followed by its poll.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from pymavlink.dialects.v20 import ardupilotmega as mavlink

from autonomy.vehicle import modes
from autonomy.vehicle.commands import CommandStep, StepGenerator
from autonomy.vehicle.fence import (
    BREACH_ACTION,
    FenceUpload,
    ardupilot_fence_type,
    describe_action,
    fence_items,
    kept_from_vehicle,
)
from autonomy.vehicle.transfers import (
    ItemFields,
    MissionDownload,
    MissionUpload,
    ParamRead,
    ParamSet,
)
from lsm.area import NoFlyZone

FENCE = mavlink.MAV_MISSION_TYPE_FENCE
_REAL32 = mavlink.MAV_PARAM_TYPE_REAL32
_INT8 = mavlink.MAV_PARAM_TYPE_INT8


@dataclass(frozen=True)
class Exchanges:
    """How a procedure starts an exchange with the autopilot; each returns the handle the
    driver follows (a procedure yields it to wait for it)."""

    upload: Callable[[str, list[ItemFields], int], MissionUpload]  # name, items, mission type
    download: Callable[[str, int], MissionDownload]  # name, mission type
    read_param: Callable[[str], ParamRead]
    set_param: Callable[[str, float, int], ParamSet]  # name, value, MAV_PARAM_TYPE
    command: Callable[[str, int, tuple[float, ...]], CommandStep]  # name, MAV_CMD, params


def upload(link: Exchanges, record: FenceUpload, autopilot: str,
           home: tuple[float, float], polygon: list[tuple[float, float]],
           exclusions: Sequence[NoFlyZone],
           max_altitude: float | None) -> StepGenerator:
    """The operating area ``polygon`` and no-fly ``exclusions`` (ENU m about ``home``, lat
    and lon degrees) and the ceiling made the autopilot's geofence; ``record`` keeps what
    was sent, what the vehicle had, and the values changed."""
    record.polygon, items = fence_items(polygon, home, autopilot, exclusions)
    # The upload replaces the vehicle's whole fence plan: read it to keep its no-fly zones.
    download = link.download("the vehicle's fence plan", FENCE)
    yield download
    record.vehicle_items = download.items
    kept, record.vehicle_fence = kept_from_vehicle(download.items)
    yield link.upload("fence plan", items + kept, FENCE)
    if autopilot == modes.PX4:
        # Only a REAL32 is set on PX4 (its integers travel byte-wise, param_value).
        if max_altitude is not None:
            yield from _change(link, record, "GF_MAX_VER_DIST", max_altitude, _REAL32)
        done = ["fence plan in force" + (
            f", GF_MAX_VER_DIST {max_altitude:g}" if max_altitude is not None else "")]
    else:
        if max_altitude is not None:
            yield from _change(link, record, "FENCE_ALT_MAX", max_altitude, _REAL32)
        # ArduPilot reads integer parameters from PARAM_SET's float (C cast), unlike PX4.
        fence_type = ardupilot_fence_type(max_altitude)
        yield from _change(link, record, "FENCE_TYPE", fence_type, _INT8)
        # Whether its fences are on when not enabled by command (restored after the flight).
        enabled = link.read_param("FENCE_ENABLE")
        yield enabled
        assert enabled.value is not None
        record.enable_before = int(enabled.value)
        yield link.command("fence enable", mavlink.MAV_CMD_DO_FENCE_ENABLE, (1.0,))
        done = [f"FENCE_TYPE {fence_type}" + (
            f", FENCE_ALT_MAX {max_altitude:g}" if max_altitude is not None else "")
            + ", enabled (MAV_CMD_DO_FENCE_ENABLE)"]
    # The breach action stays the autopilot's own; say which it is (0: report only).
    action = link.read_param(BREACH_ACTION[autopilot])
    yield action
    assert action.value is not None
    record.action = (action.param, int(action.value))
    done.append(describe_action(autopilot, int(action.value)))
    record.enabled = "; ".join(done)


def restore(link: Exchanges, record: FenceUpload) -> StepGenerator:
    """Put back what :func:`upload` changed: the vehicle's fence plan as it was downloaded,
    each parameter to the value read before, and ArduPilot's fences on or off as its
    FENCE_ENABLE says."""
    yield link.upload("fence plan", record.vehicle_items, FENCE)
    for param, (value, param_type) in record.before.items():
        yield link.set_param(param, value, param_type)
    if record.enable_before is not None:
        yield link.command("fence enable", mavlink.MAV_CMD_DO_FENCE_ENABLE,
                           (float(record.enable_before),))


def _change(link: Exchanges, record: FenceUpload, param: str, value: float,
            param_type: int) -> StepGenerator:
    """Set ``param``, having read the value it had (kept in ``record.before``)."""
    read = link.read_param(param)
    yield read
    assert read.value is not None
    record.before[param] = (read.value, param_type)
    yield link.set_param(param, value, param_type)
