"""``lander sitl``: run the embedded MAVLink SITL standalone, in real time (or faster), so
QGroundControl, MAVProxy, MAVSDK or a live driver can connect over UDP or TCP.

With no address given it serves where the real SITLs do: the ArduPilot personality listens on
TCP 5760; the PX4 personality sends, unasked, from UDP 18570 to 14550 (ground stations) and
from UDP 14580 to 14540 (SDKs such as MAVSDK), as PX4 SITL does.
"""

from __future__ import annotations

import argparse
import os

from pydantic import ValidationError

from autonomy.cli import args as types
from autonomy.errors import UserError

_DEFAULT_TCP = "127.0.0.1:5760"
# PX4 SITL's MAVLink instances: (local port, remote port) on the loopback.
_PX4_UDP_OUT = (("0.0.0.0:18570", "127.0.0.1:14550"), ("0.0.0.0:14580", "127.0.0.1:14540"))


def _address(flag: str, text: str) -> tuple[str, int]:
    from sitl.transports import parse_address

    try:
        return parse_address(text)
    except ValueError as exc:
        raise UserError(f"{flag}: {exc}") from None


def _home(text: str):
    from sitl.copter.settings import HomeSettings

    parts = text.split(",")
    if len(parts) != 3:
        raise UserError(f"--home: expected LAT,LON,ALT, got {text!r}")
    try:
        lat, lon, alt = (float(p) for p in parts)
    except ValueError:
        raise UserError(f"--home: expected three numbers LAT,LON,ALT, got {text!r}") from None
    try:
        return HomeSettings(lat=lat, lon=lon, alt=alt)
    except ValidationError as exc:
        err = exc.errors()[0]
        raise UserError(f"--home: {err['loc'][0]}: {err['msg']}") from None


def _udp_out(text: str) -> tuple[tuple[str, int], tuple[str, int]]:
    """``[LOCAL_HOST:LOCAL_PORT>]HOST:PORT`` -> (local address, peer address)."""
    local, sep, peer = text.rpartition(">")
    address = _address("--udp-out", peer)
    if address[1] == 0:  # port 0 means "any free port" to listen on, but nowhere to send to
        raise UserError(f"--udp-out: {peer}: port 0 is not an address to send to (1..65535)")
    return (_address("--udp-out", local) if sep else ("0.0.0.0", 0)), address


def _signing_key(variable: str | None) -> bytes | None:
    from autonomy.vehicle import signing_key_from_text

    if variable is None:
        return None
    text = os.environ.get(variable)
    if not text:
        raise UserError(f"--signing-key-env: {variable} is not set")
    return signing_key_from_text(text)


def _bind(flag: str, host: str, port: int, make):
    try:
        return make()
    except OSError as exc:
        reason = exc.strerror or str(exc)
        raise UserError(f"{flag}: cannot listen on {host}:{port}: {reason}") from None


def run(args: argparse.Namespace) -> int:
    from sitl import Sitl, SitlSettings
    from sitl.realtime import RealTimeRunner
    from sitl.transports import TcpServer, UdpEndpoint

    if not args.speedup > 0:
        raise UserError(f"--speedup: must be > 0, got {args.speedup}")
    if args.duration is not None and not args.duration > 0:
        raise UserError(f"--duration: must be > 0, got {args.duration}")
    if args.seed is not None and not 0 <= args.seed < 2**32:
        raise UserError(f"--seed: must be 0 .. 2**32-1, got {args.seed}")
    udp_addresses = [_address("--udp", a) for a in args.udp or []]
    tcp_addresses = [_address("--tcp", a) for a in args.tcp or []]
    udp_out = [_udp_out(a) for a in args.udp_out or []]
    if not udp_addresses and not tcp_addresses and not udp_out:
        if args.autopilot == "px4":
            udp_out = [(_address("--udp-out", a), _address("--udp-out", b))
                       for a, b in _PX4_UDP_OUT]
        else:
            tcp_addresses = [_address("--tcp", _DEFAULT_TCP)]
    key = _signing_key(args.signing_key_env)
    settings = SitlSettings()
    if args.home is not None:
        settings = settings.model_copy(update={"home": _home(args.home)})

    udp, tcp = [], []
    try:
        for host, port in udp_addresses:
            udp.append(_bind("--udp", host, port, lambda h=host, p=port: UdpEndpoint(h, p)))
        for (host, port), peer in udp_out:
            udp.append(_bind("--udp-out", host, port,
                             lambda h=host, p=port, q=peer: UdpEndpoint(h, p, peer=q)))
        for host, port in tcp_addresses:
            tcp.append(_bind("--tcp", host, port, lambda h=host, p=port: TcpServer(h, p)))
    except UserError:
        for sock in udp + tcp:
            sock.close()
        raise

    sim = Sitl(settings, autopilot=args.autopilot, seed=args.seed or 0, signing_key=key)
    runner = RealTimeRunner(sim, udp=udp, tcp=tcp, speedup=args.speedup)
    served = []
    for e in udp:
        (h, p) = e.address
        served.append(f"udp {h}:{p}" + (f" -> {e.peer[0]}:{e.peer[1]}" if e.greets else ""))
    served += [f"tcp {h}:{p}" for h, p in (s.address for s in tcp)]
    home = settings.home
    try:
        print(
            f"SITL ({args.autopilot}) home {home.lat:.6f},{home.lon:.6f},{home.alt:g} m; "
            f"serving {', '.join(served)}; speedup {args.speedup:g}x"
            f"{'; signed' if key else ''}; Ctrl-C to stop",
            flush=True,
        )
        runner.run(duration=args.duration)
    except KeyboardInterrupt:
        pass
    finally:
        runner.close()
    truth = sim.truth
    print(
        f"SITL stopped at t={sim.time:.1f} s: {runner.clients} TCP client(s), "
        f"mode {truth.mode}, {'armed' if truth.armed else 'disarmed'}, "
        f"battery {truth.battery_percent:.0f}%",
        flush=True,
    )
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "sitl",
        help="run the embedded MAVLink SITL for QGroundControl/MAVProxy",
        description="Run the embedded multicopter SITL in real time (times --speedup), "
        "serving MAVLink 2 on UDP and/or TCP. With no address it serves where the real SITL "
        f"does: ardupilot listens on tcp {_DEFAULT_TCP} (a client is greeted at once); px4 "
        "sends unasked to udp 127.0.0.1:14550 (QGroundControl) and 127.0.0.1:14540 (MAVSDK "
        "udpin://0.0.0.0:14540). A --udp port answers whoever sent to it last, so its client "
        "speaks first (e.g. mavproxy.py --master udpout:127.0.0.1:14550).",
    )
    parser.add_argument("--udp", action="append", metavar="HOST:PORT",
                        help="serve MAVLink on this UDP address (repeatable)")
    parser.add_argument("--udp-out", action="append", metavar="[LOCAL:PORT>]HOST:PORT",
                        help="send MAVLink unasked to this UDP address (from LOCAL:PORT, "
                        "default any free port), answering whoever speaks to it (repeatable)")
    parser.add_argument("--tcp", action="append", metavar="HOST:PORT",
                        help="listen for MAVLink TCP clients here (repeatable)")
    parser.add_argument("--signing-key-env", metavar="VAR",
                        help="sign MAVLink 2 with the key in this environment variable (64 hex "
                        "digits or a passphrase) and refuse unsigned packets")
    parser.add_argument("--speedup", type=types.number(0, 1000, low_open=True), default=1.0,
                        help="simulated seconds per wall-clock second (default 1)")
    parser.add_argument("--home", metavar="LAT,LON,ALT",
                        help="home position: degrees, degrees, metres AMSL "
                        "(write --home=-35.36,149.16,584 for a negative latitude)")
    parser.add_argument("--autopilot", choices=("ardupilot", "px4"), default="ardupilot",
                        help="personality (default ardupilot)")
    parser.add_argument("--seed", type=types.seed, default=0,
                        help="seed of the wind gusts (0 .. 2**32-1)")
    parser.add_argument("--duration", type=types.number(0, 1e7, low_open=True),
                        metavar="SECONDS",
                        help="stop after this many simulated seconds (default: run until Ctrl-C)")
    parser.set_defaults(func=run)
