"""Settings of the MAVLink vehicle driver (pydantic; composed into the mission schema)."""

from __future__ import annotations

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


class VehicleLinkSettings(BaseModel):
    """How the driver talks to the autopilot. Times are seconds of the injected clock."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    link_timeout: float = Field(3.0, gt=0, description="silence after which the link is lost")
    connect_timeout: float = Field(
        30.0, gt=0, description="live flights: wait this long for the autopilot's first "
        "HEARTBEAT before giving up (outcome link_lost)"
    )
    loss_wait: float = Field(
        30.0, ge=0, description="live flights: once the link is lost, hold the mission this "
        "long for it to come back before giving up (outcome link_lost); the autopilot keeps "
        "its own target or failsafe meanwhile"
    )
    heartbeat_period: float = Field(1.0, gt=0, description="our own HEARTBEAT period")
    ack_timeout: float = Field(1.0, gt=0, description="wait for a COMMAND_ACK before re-sending")
    command_attempts: int = Field(4, ge=1, le=20, description="COMMAND_LONGs sent at most")
    confirm_timeout: float = Field(
        3.0, gt=0, description="after an accepting ACK, wait this long to see the effect"
    )
    in_progress_timeout: float = Field(30.0, gt=0)
    refusal_text_grace: float = Field(
        0.5, ge=0, description="after a refusing COMMAND_ACK, wait this long for the "
        "STATUSTEXT saying why (ArduPilot sends it just after the ACK)"
    )
    setpoint_rate_ardupilot: float = Field(
        4.0, gt=0, description="Hz; GUIDED targets are re-sent because they time out"
    )
    setpoint_rate_px4: float = Field(20.0, ge=10.0, description="Hz; OFFBOARD needs a stream")
    offboard_prestream: float = Field(
        0.5, ge=0, description="setpoints stream this long before OFFBOARD is requested"
    )
    max_messages_per_poll: int = Field(2000, ge=1, description="decode budget of one poll()")
    max_backlog_bytes: int = Field(
        262144, ge=4096, description="unread bytes kept; older ones are dropped and counted"
    )
    streams: dict[str, float] = Field(default_factory=lambda: dict(DEFAULT_STREAMS))
    source_system: int = Field(255, ge=1, le=255, description="our MAVLink system id")
    source_component: int = Field(190, ge=1, le=255, description="our component id (GCS)")

    @field_validator("streams")
    @classmethod
    def _known_messages(cls, streams: dict[str, float]) -> dict[str, float]:
        for name, rate in streams.items():
            if not hasattr(mavlink, f"MAVLINK_MSG_ID_{name}"):
                raise ValueError(f"unknown MAVLink message {name!r}")
            if not rate >= 0 or rate == float("inf"):
                raise ValueError(f"{name}: rate must be a finite number of Hz >= 0 (0 = off)")
        return streams
