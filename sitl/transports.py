"""Socket transports for the SITL, so QGroundControl, MAVProxy or a driver can connect.

All sockets are non-blocking and bound where asked (normally 127.0.0.1). Each exposes the
same ``read() -> bytes`` / ``write(bytes)`` pair as :class:`sitl.link.LinkEndpoint`, so the
simulator serves them exactly like the in-memory link.
"""

from __future__ import annotations

import socket

# Bytes a slow TCP client may fall behind before its oldest pending telemetry is dropped.
_MAX_PENDING = 1 << 20


def parse_address(text: str) -> tuple[str, int]:
    """``"HOST:PORT"`` -> (host, port). Raises ValueError with a clear reason."""
    if "[" in text or text.count(":") > 1:  # [::1]:5760 or ::1:5760; no host name has ':'
        # Its clients' MAVLink links (pymavlink's) are IPv4 only, so its sockets are too.
        raise ValueError(f"{text}: an IPv6 address; the SITL serves IPv4 only, as lander and "
                         "pymavlink connect: use an IPv4 address such as 127.0.0.1 or 0.0.0.0")
    host, sep, port = text.rpartition(":")
    if not sep or not host or not port:
        raise ValueError(f"expected HOST:PORT, got {text!r}")
    try:
        number = int(port)
    except ValueError:
        raise ValueError(f"port must be a number, got {port!r}") from None
    if not 0 <= number <= 65535:
        raise ValueError(f"port must be 0..65535, got {number}")
    return host, number


class UdpEndpoint:
    """A UDP socket bound at ``(host, port)`` (port 0 = any free port).

    It answers whoever sent the last datagram, as ArduPilot does on a UDP server port, so a
    client (``mavutil.mavlink_connection("udpout:HOST:PORT")``, MAVProxy ``--master``,
    QGroundControl with a target host) must speak first. Given a ``peer``, it sends there from
    the start, unasked, as PX4 SITL sends to 14550 (ground stations) and 14540 (SDKs), until
    someone else speaks to it.
    """

    def __init__(
        self, host: str = "127.0.0.1", port: int = 0, peer: tuple[str, int] | None = None
    ) -> None:
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host, port))
        except OSError:
            self._sock.close()
            raise
        self._sock.setblocking(False)
        self.peer: tuple[str, int] | None = peer
        self.greets = peer is not None  # the server talks on it at once
        self.closed = False
        self.dropped_datagrams = 0

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port)."""
        return self._sock.getsockname()

    def read(self) -> bytes:
        chunks = []
        while True:
            try:
                data, peer = self._sock.recvfrom(65535)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:  # e.g. ICMP port unreachable from a vanished peer
                continue
            self.peer = peer
            chunks.append(data)
        return b"".join(chunks)

    def write(self, data: bytes) -> None:
        if self.peer is None or not data:
            return
        try:
            self._sock.sendto(data, self.peer)
        except OSError:
            self.dropped_datagrams += 1

    def close(self) -> None:
        if not self.closed:
            self._sock.close()
            self.closed = True


class TcpEndpoint:
    """One accepted TCP client. ``closed`` turns True when the client hangs up. The server
    greets it at once (HEARTBEAT), as ArduPilot SITL greets a new TCP client."""

    greets = True

    def __init__(self, sock: socket.socket) -> None:
        self._sock = sock
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self.peer = sock.getpeername()
        self.closed = False
        self._pending = bytearray()
        self.dropped_bytes = 0

    def read(self) -> bytes:
        chunks = []
        while not self.closed:
            try:
                data = self._sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                self.close()
                break
            if not data:
                self.close()
                break
            chunks.append(data)
        return b"".join(chunks)

    def write(self, data: bytes) -> None:
        if self.closed:
            return
        self._pending += data
        try:
            sent = self._sock.send(self._pending)
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError:
            self.close()
            return
        del self._pending[:sent]
        if len(self._pending) > _MAX_PENDING:
            # A client that cannot keep up loses old telemetry rather than stalling the sim.
            self.dropped_bytes += len(self._pending)
            self._pending.clear()

    def close(self) -> None:
        if not self.closed:
            self._sock.close()
            self.closed = True


class TcpServer:
    """A listening TCP socket; :meth:`accept` returns the clients that connected since."""

    def __init__(self, host: str = "127.0.0.1", port: int = 0) -> None:
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            self._sock.bind((host, port))
            self._sock.listen(8)
        except OSError:
            self._sock.close()
            raise
        self._sock.setblocking(False)
        self.closed = False

    @property
    def address(self) -> tuple[str, int]:
        return self._sock.getsockname()

    def accept(self) -> list[TcpEndpoint]:
        clients = []
        while not self.closed:
            try:
                sock, _ = self._sock.accept()
            except (BlockingIOError, InterruptedError):
                break
            except OSError:
                break
            clients.append(TcpEndpoint(sock))
        return clients

    def close(self) -> None:
        if not self.closed:
            self._sock.close()
            self.closed = True
