"""``lander flow-calibrate``: the descent watch's thresholds O_T and V_T for a mission's world
and camera, from an obstacle-free descent (docs/obstacle-avoidance.md).

    lander flow-calibrate MISSION --at X,Y [--top 25] [--bottom 2.5] [--speed 1.5]
                          [--seed N] [--with-moving] [--out DIR]

Flies the mission's descent camera (``perception.descent_flow``) straight down over (X, Y)
of the mission's world (built from its seed as a flight builds it) and prints the
thresholds, as YAML to paste under ``perception.descent_flow``. ``--out`` writes the first
and last frames as PNG. The world's moving obstacles are left out (a car passing the column
would raise O_T and V_T until the watch no longer sees cars); ``--with-moving`` keeps them.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from autonomy.cli import args as types
from autonomy.errors import UserError

_METRES = types.number(0.0, 10_000.0, low_open=True)  # m or m/s above 0, up to 10 km


def _point(text: str) -> tuple[float, float]:
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError:
        values = []
    if len(values) != 2 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: expected X,Y (m east, m north of home)")
    return values[0], values[1]


def register(subparsers) -> None:
    parser = subparsers.add_parser(
        "flow-calibrate", help="derive the descent watch's O_T and V_T from an open descent",
        description=__doc__.split("\n\n")[0],
    )
    parser.add_argument("mission", type=Path, help="mission YAML (its world and camera)")
    parser.add_argument("--at", type=_point, required=True, metavar="X,Y",
                        help="open ground to descend over, m east and north of home")
    parser.add_argument("--top", type=_METRES, default=25.0, help="start, m above the "
                        "ground (default 25)")
    parser.add_argument("--bottom", type=_METRES, default=2.5, help="end, m above the "
                        "ground (default 2.5, the verification altitude)")
    parser.add_argument("--speed", type=_METRES, default=1.5, help="descent speed, m/s "
                        "(default 1.5, the embedded SITL's)")
    parser.add_argument("--seed", type=types.seed, default=None, help="world seed (default: the "
                        "mission's)")
    parser.add_argument("--with-moving", action="store_true", help="keep the world's moving "
                        "obstacles (default: calibrate on the static world)")
    parser.add_argument("--out", type=Path, default=None, help="write the first and last "
                        "frames here (PNG)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autonomy.config import load_mission
    from autonomy.perception.descent_flow import DescentFlow, calibrate_descent
    from autonomy.runner.world import FlightSeeds, build_terrain

    mission = load_mission(args.mission)
    seed = mission.seed if args.seed is None else args.seed
    if args.top <= args.bottom:
        raise UserError(f"--top {args.top:g} m must be above --bottom {args.bottom:g} m")
    seeds = FlightSeeds.derive(seed)
    terrain = build_terrain(mission, seeds.terrain)
    moving = terrain.moving
    left_out = 0 if moving is None or args.with_moving else len(moving)
    if left_out:
        terrain.moving = None  # the static world: an obstacle-free column, as calibration needs
    x, y = args.at
    if not terrain.has_ground(x, y) or not terrain.contains(x, y):
        raise UserError(f"--at {x:g},{y:g}: no ground of the world there")
    settings = mission.perception.descent_flow
    o_t, v_t, pairs = calibrate_descent(
        terrain, x, y, settings=settings, top=args.top, bottom=args.bottom, speed=args.speed,
        seed=seeds.descent_flow,
    )
    print(f"# {pairs} frame pairs, {args.top:g} m to {args.bottom:g} m above ({x:g}, {y:g}) "
          f"at {args.speed:g} m/s, {settings.rate:g} Hz, {settings.width} x {settings.height} "
          f"px, world {terrain.kind} seed {seed}")
    if left_out:
        print(f"# the static world: {left_out} moving obstacle(s) left out (--with-moving "
              "keeps them)")
    elif moving is not None:
        print(f"# with the world's {len(moving)} moving obstacle(s): a pass near the column "
              "raises the thresholds")
    print("perception:\n  descent_flow:")
    print(f"    obstacle_threshold: {o_t:.4g}   # O_T\n    variance_threshold: {v_t:.4g}   # V_T")
    if args.out is not None:
        import cv2

        try:
            args.out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise UserError(f"--out {args.out}: {exc.strerror or exc}") from None
        flow = DescentFlow(terrain, settings, seeds.descent_flow)
        ground = float(terrain.height(x, y))
        for name, height in (("top", args.top), ("bottom", args.bottom)):
            shot = flow.capture((x, y, ground + height), 0.0, 0.0)
            if shot is not None:
                cv2.imwrite(str(args.out / f"frame_{name}.png"), shot[0])
        print(f"# frames: {args.out / 'frame_top.png'}, {args.out / 'frame_bottom.png'}")
    return 0
