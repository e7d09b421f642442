"""An in-memory byte pipe between the simulator and a MAVLink client.

Everything that crosses a :class:`MemoryLink` is real MAVLink bytes, exactly as it would be on a
serial line or a socket, but without the operating system in between: the simulator and the
autonomy's driver can run in lockstep in one process.
"""

from __future__ import annotations

import threading


class LinkEndpoint:
    """One side of an in-memory byte pipe.

    ``write`` appends bytes for the peer; ``read`` returns everything the peer wrote since the
    last ``read`` (or ``b""``). Both are thread-safe, so the two sides may live in different
    threads.
    """

    def __init__(self, inbox: list[bytes], outbox: list[bytes], lock: threading.Lock) -> None:
        self._inbox = inbox
        self._outbox = outbox
        self._lock = lock
        self.bytes_written = 0
        self.bytes_read = 0

    def write(self, data: bytes) -> None:
        """Append ``data`` for the peer to read."""
        if not data:
            return
        with self._lock:
            self._outbox.append(bytes(data))
        self.bytes_written += len(data)

    def read(self) -> bytes:
        """Everything the peer wrote since the last call, or ``b""``."""
        if not self._inbox:  # nothing written (a list's length is read atomically)
            return b""
        with self._lock:
            chunks = self._inbox[:]
            self._inbox.clear()
        data = chunks[0] if len(chunks) == 1 else b"".join(chunks)
        self.bytes_read += len(data)
        return data


class MemoryLink:
    """A pair of connected endpoints: ``vehicle`` for the simulator, ``gcs`` for the driver."""

    def __init__(self) -> None:
        lock = threading.Lock()
        to_vehicle: list[bytes] = []
        to_gcs: list[bytes] = []
        self.vehicle = LinkEndpoint(inbox=to_vehicle, outbox=to_gcs, lock=lock)
        self.gcs = LinkEndpoint(inbox=to_gcs, outbox=to_vehicle, lock=lock)
