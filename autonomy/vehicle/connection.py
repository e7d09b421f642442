"""Opening a link to a vehicle: URLs, byte transports, signing keys.

URLs are the ones pymavlink knows (``udp:``/``udpin:HOST:PORT`` listen, ``udpout:HOST:PORT``
sends, ``tcp:HOST:PORT`` connects, ``tcpin:HOST:PORT`` listens, a serial device path with an
optional ``,BAUD``) plus ``sim://[ardupilot|px4][?seed=N]``, the in-memory lockstep link to an
embedded :class:`sitl.Sitl`.
"""

from __future__ import annotations

import errno
import hashlib
import os
import re
import socket
import string
import time
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, urlsplit

from autonomy.clock import VehicleClock
from autonomy.errors import UserError
from autonomy.vehicle.driver import MavlinkVehicle
from autonomy.vehicle.settings import VehicleLinkSettings
from autonomy.vehicle.tlog import SIM_EPOCH
from behaviors.ports import Clock

SIGNING_KEY_ENV = "LANDER_SIGNING_KEY"
_NETWORK_SCHEMES = ("udp", "udpin", "udpout", "tcp", "tcpin")
_SERIAL = re.compile(r"^(?P<device>(/dev/|COM\d|\\\\\.\\)[^,]*)(,(?P<baud>\d+))?$")
_UDP_CHUNKS_PER_READ = 256  # datagrams drained per read(); the rest wait for the next poll


class MemoryTransport:
    """The driver's side of a :class:`sitl.link.MemoryLink` (``read``/``write`` bytes)."""

    def __init__(self, endpoint: Any, description: str = "sim://", on_close: Any = None) -> None:
        self._endpoint = endpoint
        self.description = description
        self.closed = False
        self._on_close = on_close  # e.g. detach the endpoint from the simulator

    def read(self) -> bytes:
        return b"" if self.closed else self._endpoint.read()

    def write(self, data: bytes) -> None:
        if not self.closed:
            self._endpoint.write(data)

    def close(self) -> None:
        if not self.closed and self._on_close is not None:
            self._on_close()
        self.closed = True


class PymavlinkTransport:
    """A pymavlink connection (socket or serial port) used as a raw, non-blocking byte pipe;
    the driver does its own parsing so that it can bound, count and log every packet."""

    def __init__(self, connection: Any, description: str) -> None:
        from pymavlink import mavutil

        self._conn = connection
        self.description = description
        # A TCP client socket is read directly: pymavlink prints a line on every read after
        # the peer hung up; here the hang-up is noted once and the link then goes quiet.
        self._stream = connection.port if isinstance(connection, mavutil.mavtcp) else None
        self.peer_closed = False

    def read(self) -> bytes:
        if self._stream is not None:
            return self._read_stream(self._stream)
        chunks = []
        for _ in range(_UDP_CHUNKS_PER_READ):
            data = self._conn.recv(65536)
            if not data:
                break
            chunks.append(data if isinstance(data, bytes) else bytes(data, "latin-1"))
        return b"".join(chunks)

    def _read_stream(self, sock: socket.socket) -> bytes:
        chunks = []
        while not self.peer_closed:
            try:
                data = sock.recv(65536)
            except (BlockingIOError, InterruptedError):
                break
            except ConnectionError:
                data = b""
            if not data:
                self.peer_closed = True
                break
            chunks.append(data)
        return b"".join(chunks)

    def write(self, data: bytes) -> None:
        if not self.peer_closed:
            self._conn.write(data)

    def close(self) -> None:
        self._conn.close()


def signing_key_from_text(text: str) -> bytes:
    """A 32-byte MAVLink signing key: 64 hex digits as they are, else sha256 of a passphrase."""
    text = text.strip()
    if not text:
        raise UserError(f"{SIGNING_KEY_ENV}: the signing key is empty")
    if len(text) == 64 and all(c in string.hexdigits for c in text):
        return bytes.fromhex(text)
    return hashlib.sha256(text.encode("utf-8")).digest()


_UNKNOWN_LINK = ("unknown link; use sim://, udpin:HOST:PORT, udpout:HOST:PORT, tcp:HOST:PORT, "
                 "tcpin:HOST:PORT or a serial device such as /dev/ttyACM0,115200")


# pymavlink's network links (mavutil's mavudp, mavtcp, mavtcpin) open IPv4 sockets only.
IPV6_REFUSED = ("an IPv6 address; MAVLink network links are IPv4 only here (pymavlink): use "
                "an IPv4 address or a host name that has one")


def check_url(url: str) -> str:
    """``url`` stripped, if it is a link :func:`connect` can open: its form only (scheme,
    HOST:PORT, serial device and baud, the simulator's personality and options), nothing is
    opened or resolved.

    Raises:
        ValueError: the reason, e.g. ``unknown link; use sim://, ...``.
    """
    if not isinstance(url, str) or not url.strip():
        raise ValueError("empty; use sim:// for the embedded simulator")
    url = url.strip()
    if any(not c.isprintable() for c in url):
        raise ValueError("contains control characters")
    if url == "sim" or url.startswith("sim:"):
        if not url.startswith("sim://"):
            raise ValueError("the simulator link is written sim://[ardupilot|px4]")
        _sim_options(url)
        return url
    scheme, sep, rest = url.partition(":")
    if sep and scheme in _NETWORK_SCHEMES:
        if "[" in rest or rest.count(":") > 1:  # [::1]:5760 or ::1:5760; no host name has ':'
            port = rest.rpartition(":")[2]
            raise ValueError(f"{rest}: {IPV6_REFUSED}, e.g. {scheme}:127.0.0.1:"
                             f"{port if port.isdigit() else 5760}")
        host, sep, port = rest.rpartition(":")
        if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
            raise ValueError("expected HOST:PORT after the scheme, port 0..65535 (e.g. "
                             "udpin:0.0.0.0:14550)")
        if any(c.isspace() for c in host):
            raise ValueError(f"host {host!r} contains white space")
        if int(port) == 0 and scheme in ("udpout", "tcp"):  # 0: any port to listen on only
            raise ValueError(f"port 0 is not an address to reach ({scheme}:HOST:1..65535)")
        return url
    serial = _SERIAL.match(url)
    if serial is not None:
        baud = serial.group("baud")
        if baud is not None and not 50 <= int(baud) <= 20_000_000:
            raise ValueError(f"baud rate {baud}: expected 50 .. 20000000")
        return url
    raise ValueError(_UNKNOWN_LINK)


def _sim_options(url: str) -> tuple[str, int]:
    """(personality, seed) of a ``sim://`` URL; ValueError when it names anything else."""
    parts = urlsplit(url)
    autopilot = parts.netloc or parts.path.strip("/") or "ardupilot"
    if autopilot not in ("ardupilot", "px4"):
        raise ValueError(f"the simulator flies 'ardupilot' or 'px4', not {autopilot!r}")
    query = parse_qs(parts.query, keep_blank_values=True)
    unknown = set(query) - {"seed"}
    if unknown or (parts.query and not query):
        raise ValueError(f"unknown option {sorted(unknown)[0] if unknown else parts.query!r} "
                         "(known: seed)")
    text = query.get("seed", ["0"])[-1]
    if not text.isdigit() or not 0 <= int(text) <= 2**32 - 1:
        raise ValueError(f"seed must be an integer 0 .. 2**32-1, got {text!r}")
    return autopilot, int(text)


def _host_port(url: str, rest: str) -> tuple[str, int]:
    host, sep, port = rest.rpartition(":")
    if not sep or not host or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise UserError(f"{url}: expected HOST:PORT after the scheme (e.g. udpin:0.0.0.0:14550)")
    return host, int(port)


def _resolves(host: str, port: int) -> bool:
    try:
        return bool(socket.getaddrinfo(host, port))
    except socket.gaierror:
        return False


def _check_free(url: str, host: str, port: int, kind: int) -> None:
    """pymavlink binds with SO_REUSEADDR, which hides a port held by another program."""
    if port == 0:
        return
    probe = socket.socket(socket.AF_INET, kind)
    try:
        probe.bind((host, port))
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise UserError(f"{url}: port {port} is already in use") from exc
        raise UserError(f"{url}: cannot listen on {host}:{port} ({exc.strerror})") from exc
    finally:
        probe.close()


def open_transport(url: str, baud: int = 115200) -> PymavlinkTransport:
    """Open a pymavlink link for a network or serial URL; UserError on any failure."""
    from pymavlink import mavutil

    scheme, sep, rest = url.partition(":")
    serial = _SERIAL.match(url)
    try:
        if sep and scheme in _NETWORK_SCHEMES:
            host, port = _host_port(url, rest)
            try:
                socket.getaddrinfo(host, port, socket.AF_INET)
            except socket.gaierror as exc:
                if _resolves(host, port):  # to IPv6 addresses only
                    raise UserError(f"{url}: {host} has no IPv4 address; MAVLink network "
                                    "links are IPv4 only here (pymavlink)") from exc
                raise UserError(f"{url}: unknown host {host!r}") from exc
            if scheme in ("udp", "udpin"):
                _check_free(url, host, port, socket.SOCK_DGRAM)
            conn = mavutil.mavlink_connection(
                f"{scheme}:{host}:{port}", source_system=255, retries=0, autoreconnect=False
            )
        elif serial is not None:
            device = serial.group("device")
            if serial.group("baud"):
                baud = int(serial.group("baud"))
            conn = mavutil.mavlink_connection(device, baud=baud, autoreconnect=False)
        else:
            raise UserError(f"{url}: {_UNKNOWN_LINK}")
    except UserError:
        raise
    except ConnectionRefusedError as exc:
        raise UserError(f"{url}: connection refused (is the autopilot running?)") from exc
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            raise UserError(f"{url}: port is already in use") from exc
        raise UserError(f"{url}: cannot open ({exc.strerror or exc})") from exc
    except Exception as exc:  # pyserial and pymavlink raise their own types
        raise UserError(f"{url}: cannot open ({exc})") from exc
    return PymavlinkTransport(conn, url)


def _open_sim(url: str, sitl: Any, signing_key: bytes | None) -> tuple[MemoryTransport, Any, bool]:
    try:
        autopilot, seed = _sim_options(url)
    except ValueError as exc:
        raise UserError(f"{url}: {exc}") from None
    from sitl.link import MemoryLink

    owns = sitl is None
    if owns:
        from sitl import Sitl

        sitl = Sitl(autopilot=autopilot, seed=seed, signing_key=signing_key)
    link = MemoryLink()
    sitl.attach(link.vehicle)
    # A simulator that outlives the vehicle must stop writing into a link nobody reads.
    detach = None if owns else (lambda: sitl.detach(link.vehicle))
    return MemoryTransport(link.gcs, url, on_close=detach), sitl, owns


def connect(
    url: str,
    clock: Clock,
    *,
    sitl: Any = None,
    signing_key: bytes | None = None,
    link_timeout: float = 3.0,
    target_system: int | None = None,
    tlog_path: str | Path | None = None,
    settings: VehicleLinkSettings | None = None,
) -> MavlinkVehicle:
    """Open ``url`` and return a :class:`MavlinkVehicle` on it (it has sent its first
    HEARTBEAT; call ``poll()`` to hear the autopilot).

    Args:
        url: see the module docstring. ``sim://`` uses ``sitl`` if given, else creates an
            embedded simulator owned (and closed) by the vehicle; either is ``vehicle.sitl``.
        clock: injected time source (a SimClock for sim://, a VehicleClock for live links,
            which the vehicle then feeds with the autopilot's time stamps).
        signing_key: 32-byte MAVLink 2 signing key; default: ``$LANDER_SIGNING_KEY`` (64 hex
            digits, or a passphrase hashed with sha256), else no signing.
        link_timeout: seconds of autopilot silence after which ``state.link_lost`` is set.
        target_system: system id to talk to (default: the first autopilot heard).
        tlog_path: write a MAVLink telemetry log of both directions there.

    Raises:
        UserError: unknown scheme, bad address, port in use, peer unreachable, bad key.
    """
    try:
        url = check_url(url)
    except ValueError as exc:
        raise UserError(f"{str(url).strip() or 'vehicle url'}: {exc}") from None
    if signing_key is None and os.environ.get(SIGNING_KEY_ENV):
        signing_key = signing_key_from_text(os.environ[SIGNING_KEY_ENV])
    if signing_key is not None and len(signing_key) != 32:
        raise UserError(f"signing key: must be 32 bytes, got {len(signing_key)}")
    if link_timeout <= 0:
        raise UserError(f"link_timeout: must be > 0 s, got {link_timeout}")
    owns = False
    if url.startswith("sim://"):
        transport: Any
        transport, sitl, owns = _open_sim(url, sitl, signing_key)
        epoch = SIM_EPOCH
    else:
        transport = open_transport(url)
        epoch = time.time() - clock.now()
    try:
        return MavlinkVehicle(
            transport,
            clock,
            settings=settings,
            link_timeout=link_timeout,
            signing_key=signing_key,
            target_system=target_system,
            tlog_path=tlog_path,
            tlog_epoch=epoch,
            sitl=sitl,
            owns_sitl=owns,
            on_vehicle_time=clock.observe if isinstance(clock, VehicleClock) else None,
        )
    except BaseException:
        transport.close()
        if owns and sitl is not None:
            sitl.close()
        raise
