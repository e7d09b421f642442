"""Settings of the MAVLink vehicle driver (pydantic; composed into the mission schema)."""

from __future__ import annotations

from typing import Annotated

from pydantic import BaseModel, ConfigDict, Field, field_validator
from pymavlink.dialects.v20 import ardupilotmega as mavlink

# Telemetry the driver asks for with MAV_CMD_SET_MESSAGE_INTERVAL, in Hz.
DEFAULT_STREAMS: dict[str, float] = {
    "LOCAL_POSITION_NED": 10.0,
    "ATTITUDE": 10.0,
    "DISTANCE_SENSOR": 10.0,
    "SYS_STATUS": 2.0,
    "EXTENDED_SYS_STATE": 2.0,
    "GPS_RAW_INT": 2.0,
    "HOME_POSITION": 0.5,
    "EKF_STATUS_REPORT": 1.0,  # ArduPilot: whether it has a position estimate
}
LOG_STREAMS: dict[str, float] = {
    "GLOBAL_POSITION_INT": 5.0,
    "VFR_HUD": 4.0,
}
"""Asked for as well when a telemetry log is written (unless ``streams`` names them): not read
by the flight, but what log viewers (MAVExplorer, UAV Log Viewer) draw from flight.tlog, the
track on a map and the HUD, at the rates ground stations ask for."""


MAX_WAIT = 3_600.0
"""s: the longest wait or timeout of the link; an hour is more than a multicopter's battery
can hover while the driver waits."""
MAX_RATE = 100.0
"""Hz: the fastest telemetry or setpoint stream; autopilots stream at up to 50 Hz, and a
57600-baud telemetry radio carries a few hundred small messages a second in all."""


class VehicleLinkSettings(BaseModel):
    """How the driver talks to the autopilot. Times are seconds of the injected clock."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    link_timeout: float = Field(
        3.0, gt=0, le=MAX_WAIT, description="silence after which the link is lost, s, up to "
        "an hour"
    )
    connect_timeout: float = Field(
        30.0, gt=0, le=MAX_WAIT, description="live flights: wait this long (s, up to an hour) "
        "for the autopilot's first HEARTBEAT before giving up (outcome link_lost)"
    )
    loss_wait: float = Field(
        30.0, ge=0, le=MAX_WAIT, description="live flights: once the link is lost, hold the "
        "mission this long (s, up to an hour) for it to come back before giving up (outcome "
        "link_lost); the autopilot keeps its own target or failsafe meanwhile"
    )
    heartbeat_period: float = Field(
        1.0, gt=0, le=60, description="our own HEARTBEAT period, s, up to a minute (MAVLink "
        "expects 1 Hz; autopilots call a ground station lost after a few seconds)"
    )
    ack_timeout: float = Field(
        1.0, gt=0, le=60, description="wait for a COMMAND_ACK before re-sending, s, up to a "
        "minute"
    )
    command_attempts: int = Field(4, ge=1, le=20, description="COMMAND_LONGs sent at most")
    confirm_timeout: float = Field(
        3.0, gt=0, le=MAX_WAIT, description="after an accepting ACK, wait this long (s, up to "
        "an hour) to see the effect"
    )
    in_progress_timeout: float = Field(
        30.0, gt=0, le=MAX_WAIT, description="after a MAV_RESULT_IN_PROGRESS ACK, wait this "
        "long (s, up to an hour) for the final one"
    )
    refusal_text_grace: float = Field(
        0.5, ge=0, le=60, description="after a refusing COMMAND_ACK, wait this long (s, up to "
        "a minute) for the STATUSTEXT saying why (ArduPilot sends it just after the ACK)"
    )
    setpoint_rate_ardupilot: float = Field(
        4.0, gt=0, le=MAX_RATE, description="Hz, up to 100; GUIDED targets are re-sent "
        "because they time out"
    )
    setpoint_rate_px4: float = Field(
        20.0, ge=10.0, le=MAX_RATE, description="Hz, 10..100; OFFBOARD needs a stream of at "
        "least 2 Hz, PX4 recommends more"
    )
    offboard_prestream: float = Field(
        0.5, ge=0, le=60, description="setpoints stream this long (s, up to a minute) before "
        "OFFBOARD is requested"
    )
    max_messages_per_poll: int = Field(
        2000, ge=1, le=1_000_000, description="decode budget of one poll(), up to a million "
        "(some seconds of decoding)"
    )
    max_backlog_bytes: int = Field(
        262144, ge=4096, le=1 << 30, description="unread bytes kept, 4 KiB .. 1 GiB (memory); "
        "older ones are dropped and counted"
    )
    streams: dict[str, Annotated[float, Field(ge=0, le=MAX_RATE)]] = Field(
        default_factory=lambda: dict(DEFAULT_STREAMS),
        description="telemetry asked for with SET_MESSAGE_INTERVAL: MAVLink message name -> "
        "Hz, 0 (off) .. 100; with a telemetry log, GLOBAL_POSITION_INT (5 Hz) and VFR_HUD "
        "(4 Hz) too unless named here",
    )
    source_system: int = Field(255, ge=1, le=255, description="our MAVLink system id")
    source_component: int = Field(190, ge=1, le=255, description="our component id (GCS)")

    @field_validator("streams")
    @classmethod
    def _known_messages(cls, streams: dict[str, float]) -> dict[str, float]:
        for name in streams:
            if not hasattr(mavlink, f"MAVLINK_MSG_ID_{name}"):
                raise ValueError(f"unknown MAVLink message {name!r}")
        return streams
