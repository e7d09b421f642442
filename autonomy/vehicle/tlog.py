"""MAVLink telemetry logs (``.tlog``), the format MAVProxy, QGroundControl and pymavlink read.

Each record is an 8-byte big-endian timestamp in microseconds since the Unix epoch followed
by one raw MAVLink packet. The driver logs both directions; timestamps are the injected
clock's time plus an epoch offset (wall time at connect for live links, a fixed date for
simulated time, so logs of lockstep runs are reproducible).
"""

from __future__ import annotations

import struct
from pathlib import Path

from autonomy.errors import UserError

# 2026-01-01T00:00:00Z: where simulated time starts in the logs of lockstep runs.
SIM_EPOCH = 1767225600.0

_STAMP = struct.Struct(">Q")


class TlogWriter:
    """Appends timestamped raw packets to a ``.tlog`` file.

    Args:
        path: file to create (parent folders are made; an existing file is replaced).
        epoch: seconds since the Unix epoch that clock time 0 stands for.
    """

    def __init__(self, path: str | Path, epoch: float) -> None:
        self.path = Path(path)
        self.epoch = float(epoch)
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = open(self.path, "wb")  # closed by close()
        except OSError as exc:
            reason = exc.strerror or exc
            raise UserError(f"{self.path}: cannot write the telemetry log ({reason})") from exc
        self.packets = 0

    def write(self, packet: bytes | bytearray, clock_time: float) -> None:
        """Log one raw MAVLink packet seen or sent at ``clock_time`` (clock s)."""
        if self._file.closed:
            return
        stamp = int(round((self.epoch + clock_time) * 1e6))
        self._file.write(_STAMP.pack(stamp) + packet)
        self.packets += 1

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()

    def __enter__(self) -> TlogWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
