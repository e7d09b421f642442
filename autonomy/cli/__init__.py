"""The ``lander`` command line.

Each subcommand lives in its own module in this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable taking the
parsed arguments and returning an exit code. Bad user input raises
:class:`autonomy.errors.UserError`; :func:`main` prints it as one line and exits 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from autonomy import __version__
from autonomy.errors import UserError

# Subcommand modules, in the order `lander --help` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "autonomy.cli.fly",
    "autonomy.cli.demo",
    "autonomy.cli.validate",
    "autonomy.cli.tree",
    "autonomy.cli.campaign",
    "autonomy.cli.sitl",
    "autonomy.cli.detect",
    "autonomy.cli.link",
    "autonomy.cli.terrain",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="lander",
        description="Behavior-tree landing autonomy for UAVs over MAVLink.",
    )
    parser.add_argument("--version", action="version", version=f"lander {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"lander {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"lander {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`lander tree ... | head`): stop quietly, as cat does.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
