"""``lander link``: connect the MAVLink driver to a vehicle and print what it reports, once a
second: a quick check of a connection (URL, signing key, streams) before flying a mission."""

from __future__ import annotations

import argparse
import os
import time

from autonomy.cli import args as types
from autonomy.errors import UserError

_TICK = 0.05  # s between polls (20 Hz, the runner's default rate)


def _line(state, stats) -> str:
    pos = "-" if state.position is None else "({:.1f}, {:.1f}, {:.1f})".format(*state.position)
    battery = "-" if state.battery_percent is None else f"{state.battery_percent:.0f}%"
    agl = "-" if state.rangefinder_agl is None else f"{state.rangefinder_agl:.1f} m"
    link = "LOST" if state.link_lost else f"hb {state.heartbeat_age:.1f} s"
    text = f'  "{state.last_status_text}"' if state.last_status_text else ""
    return (
        f"t={state.time:6.1f} s  {state.autopilot:9s} {state.mode or '-':12s} "
        f"{'armed' if state.armed else 'disarmed':8s} {state.landed_state.value:9s} "
        f"enu={pos} agl={agl} gps={state.gps_fix} batt={battery} "
        f"prearm={'ok' if state.prearm_ok else 'no'} link={link} msgs={stats.messages}{text}"
    )


def run(args: argparse.Namespace) -> int:
    from autonomy.clock import SimClock, WallClock
    from autonomy.vehicle import connect, signing_key_from_text

    if not args.duration > 0:
        raise UserError(f"--duration: must be > 0, got {args.duration}")
    if not args.link_timeout > 0:
        raise UserError(f"--link-timeout: must be > 0, got {args.link_timeout}")
    key = None
    if args.signing_key_env:
        text = os.environ.get(args.signing_key_env)
        if text is None:
            raise UserError(f"--signing-key-env: {args.signing_key_env} is not set")
        key = signing_key_from_text(text)
    lockstep = args.url.startswith("sim:")
    clock = SimClock() if lockstep else WallClock()
    vehicle = connect(
        args.url,
        clock,
        signing_key=key,
        link_timeout=args.link_timeout,
        target_system=args.target_system,
        tlog_path=args.tlog,
    )
    heard = False
    try:
        next_print = 1.0
        while clock.now() < args.duration:
            if lockstep:
                vehicle.sitl.step(_TICK)
                clock.advance(_TICK)
            else:
                time.sleep(_TICK)
            state = vehicle.poll()
            heard = heard or not state.link_lost
            if clock.now() >= next_print - 1e-9:
                print(_line(state, vehicle.stats), flush=True)
                next_print += 1.0
    except KeyboardInterrupt:
        pass
    finally:
        vehicle.close()
    s = vehicle.stats
    print(
        f"{args.url}: {s.messages} messages, {s.corrupt_bytes} corrupt bytes, "
        f"{s.bad_signature} bad signatures, {s.ignored} from other systems, "
        f"{s.messages_sent} sent; link lost {s.links_lost} time(s)"
        + (f"; log {args.tlog}" if args.tlog else "")
    )
    if not heard:
        print(f"lander link: no autopilot heard on {args.url}", flush=True)
        return 1
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "link",
        help="connect to a vehicle over MAVLink and print its state",
        description="Connect the MAVLink driver to URL and print the vehicle state once a "
        "second. URL: sim://[ardupilot|px4] (embedded SITL, lockstep), udpin:HOST:PORT, "
        "udpout:HOST:PORT, tcp:HOST:PORT, tcpin:HOST:PORT or a serial device "
        "(/dev/ttyACM0,115200). Exit 1 if no autopilot was heard. The signing key is read "
        "from $LANDER_SIGNING_KEY unless --signing-key-env names another variable.",
    )
    parser.add_argument("url", help="where the vehicle is")
    parser.add_argument("--duration", type=types.number(0, 86_400, low_open=True), default=10.0,
                        help="seconds to listen (clock time; simulated for sim://) (default 10)")
    parser.add_argument("--link-timeout", type=types.number(0, 3600, low_open=True),
                        default=3.0,
                        help="silence after which the link counts as lost, s (default 3)")
    parser.add_argument("--target-system", type=types.integer(1, 255), default=None,
                        help="talk only to this MAVLink system id (default: first autopilot)")
    parser.add_argument("--tlog", default=None, help="write a MAVLink telemetry log here")
    parser.add_argument("--signing-key-env", default=None, metavar="VAR",
                        help="environment variable holding the signing key (hex or passphrase)")
    parser.set_defaults(func=run)
