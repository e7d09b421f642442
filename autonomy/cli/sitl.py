"""``lander sitl``: run the embedded MAVLink SITL standalone, in real time (or faster), so
QGroundControl, MAVProxy or a live driver can connect over UDP or TCP on 127.0.0.1."""

from __future__ import annotations

import argparse

from pydantic import ValidationError

from autonomy.errors import UserError

_DEFAULT_TCP = "127.0.0.1:5760"


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


def run(args: argparse.Namespace) -> int:
    from sitl import Sitl, SitlSettings
    from sitl.realtime import RealTimeRunner
    from sitl.transports import TcpServer, UdpEndpoint

    if not args.speedup > 0:
        raise UserError(f"--speedup: must be > 0, got {args.speedup}")
    if args.duration is not None and not args.duration > 0:
        raise UserError(f"--duration: must be > 0, got {args.duration}")
    udp_addresses = [_address("--udp", a) for a in args.udp or []]
    tcp_addresses = [_address("--tcp", a) for a in args.tcp or []]
    if not udp_addresses and not tcp_addresses:
        tcp_addresses = [_address("--tcp", _DEFAULT_TCP)]
    settings = SitlSettings()
    if args.home is not None:
        settings = settings.model_copy(update={"home": _home(args.home)})

    sockets: list = []
    try:
        udp, tcp = [], []
        for flag, addresses, cls, out in (
            ("--udp", udp_addresses, UdpEndpoint, udp),
            ("--tcp", tcp_addresses, TcpServer, tcp),
        ):
            for host, port in addresses:
                try:
                    sock = cls(host, port)
                except OSError as exc:
                    reason = exc.strerror or str(exc)
                    raise UserError(f"{flag}: cannot listen on {host}:{port}: {reason}") from None
                sockets.append(sock)
                out.append(sock)
    except UserError:
        for sock in sockets:
            sock.close()
        raise

    sim = Sitl(settings, autopilot=args.autopilot, seed=args.seed)
    runner = RealTimeRunner(sim, udp=udp, tcp=tcp, speedup=args.speedup)
    served = [f"udp {h}:{p}" for h, p in (e.address for e in udp)]
    served += [f"tcp {h}:{p}" for h, p in (s.address for s in tcp)]
    home = settings.home
    try:
        print(
            f"SITL ({args.autopilot}) home {home.lat:.6f},{home.lon:.6f},{home.alt:g} m; "
            f"serving {', '.join(served)}; speedup {args.speedup:g}x; Ctrl-C to stop",
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
        "serving MAVLink 2 on UDP and/or TCP. With neither --udp nor --tcp it listens on "
        f"tcp {_DEFAULT_TCP}. The UDP port answers whoever sent to it last, so the client "
        "speaks first (e.g. mavproxy.py --master udpout:127.0.0.1:14550).",
    )
    parser.add_argument("--udp", action="append", metavar="HOST:PORT",
                        help="serve MAVLink on this UDP address (repeatable)")
    parser.add_argument("--tcp", action="append", metavar="HOST:PORT",
                        help="listen for MAVLink TCP clients here (repeatable)")
    parser.add_argument("--speedup", type=float, default=1.0,
                        help="simulated seconds per wall-clock second (default 1)")
    parser.add_argument("--home", metavar="LAT,LON,ALT",
                        help="home position: degrees, degrees, metres AMSL "
                        "(write --home=-35.36,149.16,584 for a negative latitude)")
    parser.add_argument("--autopilot", choices=("ardupilot", "px4"), default="ardupilot",
                        help="personality (default ardupilot)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the wind gusts")
    parser.add_argument("--duration", type=float, metavar="SECONDS",
                        help="stop after this many simulated seconds (default: run until Ctrl-C)")
    parser.set_defaults(func=run)
