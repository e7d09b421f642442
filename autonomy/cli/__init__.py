"""The ``lander`` command line.

Each subcommand lives in its own module in this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a callable taking the
parsed arguments and returning an exit code. Bad user input raises
:class:`autonomy.errors.UserError`; :func:`main` prints it as one line and exits 2.

Exit codes of every command: 0 done (``fly``: landed), 1 did not succeed (``fly``: did not
land as planned; ``link``: no autopilot heard; ``campaign``: a run's worker process died
twice, e.g. out of memory), 2 bad input (a file, a flag, a value, a URL,
a port in use; ``fly``: also refused before takeoff), 3 and 4 ``fly`` only (a live landing
not judged; link lost), 130 interrupted (Ctrl-C) before a flight started, 141 the reader of
the output went away, 70 an internal error (a bug: one line says so; ``LANDER_TRACEBACK=1``
shows the traceback).
"""

from __future__ import annotations

import argparse
import errno
import importlib
import io
import os
import sys

from autonomy import __version__
from autonomy.errors import UserError, one_line

# Subcommand modules, in the order `lander --help` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "autonomy.cli.fly",
    "autonomy.cli.demo",
    "autonomy.cli.validate",
    "autonomy.cli.tree",
    "autonomy.cli.campaign",
    "autonomy.cli.replay",
    "autonomy.cli.sitl",
    "autonomy.cli.detect",
    "autonomy.cli.link",
    "autonomy.cli.terrain",
    "autonomy.cli.flow",
)
EXIT_INTERNAL_ERROR = 70  # sysexits.h EX_SOFTWARE
# A file the machine refuses (a full disk, a read-only or forbidden folder) is a problem of
# where the input or output is, not a bug: one line naming the file, exit 2.
FULL_OR_READ_ONLY = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})
FILE_REFUSALS = FULL_OR_READ_ONLY | {errno.EACCES, errno.EPERM}
TRACEBACK_ENV = "LANDER_TRACEBACK"


class Parser(argparse.ArgumentParser):
    """argparse with one-line errors: ``lander fly: error: ... (lander fly --help)``."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="lander",
        description="Behavior-tree landing autonomy for UAVs over MAVLink.",
    )
    parser.add_argument("--version", action="version", version=f"lander {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(subparsers)
    return parser


def _replace_unencodable_output() -> None:
    """A terminal that cannot show a character (PYTHONIOENCODING=ascii, a Latin-1 locale)
    gets an escape for it instead of the command failing on a mission's or a path's name."""
    for stream in (sys.stdout, sys.stderr):
        if isinstance(stream, io.TextIOWrapper) and stream.errors == "strict":
            stream.reconfigure(errors="backslashreplace")


def main(argv: list[str] | None = None) -> int:
    _replace_unencodable_output()
    try:
        parser = build_parser()  # imports every command's modules: seconds on a cold start
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        print("lander: interrupted", file=sys.stderr)
        return 130
    except SystemExit as exc:  # --help, --version, or a bad flag (its line is printed)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        for problem in getattr(exc, "problems", None) or [str(exc)]:
            print(f"lander {args.command}: error: {one_line(problem, 2000)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"lander {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # The reader went away (`lander tree ... | head`): stop quietly, as cat does.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 141
    except OSError as exc:
        if exc.errno not in FILE_REFUSALS:
            return _internal_error(args.command, exc)
        where = f"{exc.filename}: " if exc.filename else ""
        partial = ("; what it was writing may be incomplete"
                   if exc.errno in FULL_OR_READ_ONLY else "")
        print(f"lander {args.command}: error: {where}{exc.strerror or exc}{partial}",
              file=sys.stderr)
        return 2
    except Exception as exc:  # a bug: one line, not a traceback (unless asked for)
        return _internal_error(args.command, exc)


def _internal_error(command: str, exc: Exception) -> int:
    """A bug: one line, not a traceback (unless asked for)."""
    if os.environ.get(TRACEBACK_ENV):
        raise exc
    print(
        f"lander {command}: internal error: {type(exc).__name__}: "
        f"{one_line(str(exc), 300)} (a bug; {TRACEBACK_ENV}=1 shows where it happened)",
        file=sys.stderr,
    )
    return EXIT_INTERNAL_ERROR


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
