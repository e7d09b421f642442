"""``lander replay OUT_DIR``: open a flight's report.html (or a campaign's campaign.html).

    lander replay out/demo            # opens out/demo/report.html in the default browser
    lander replay out/demo --print    # prints its path instead (also without a display)

A folder whose flight was killed before it wrote its report (events.jsonl, flight.tlog and
tree.btlog are written as it flies) gets a report.html rebuilt from those logs.
"""

from __future__ import annotations

import argparse
import os
import sys
import webbrowser
from pathlib import Path

from autonomy.errors import UserError

PAGES = ("report.html", "campaign.html")


def find_page(folder: Path) -> Path:
    """The report page of ``folder``: a flight's report.html, else a campaign's
    campaign.html, else a report.html rebuilt from the logs of a flight that did not finish
    (:mod:`autonomy.report.rebuild`); raises :class:`UserError` saying what is missing."""
    if not folder.exists():
        raise UserError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise UserError(f"{folder}: not a folder (give the output folder of lander fly, demo "
                        "or campaign)")
    for name in PAGES:
        if (folder / name).is_file():
            return folder / name
    if (folder / "events.jsonl").is_file():  # a flight killed before it wrote its report
        from autonomy.cli.outdir import writing_into
        from autonomy.report.rebuild import rebuild_page

        with writing_into(folder, "the rebuilt report.html"):
            page = rebuild_page(folder)
        print(f"{folder}: the flight did not write its report; {page.name} rebuilt from its "
              "logs (track, phases, events, tree log to its last transition)", file=sys.stderr)
        return page
    raise UserError(f"{folder}: no report.html or campaign.html, nor events.jsonl to rebuild "
                    "a page from (not the output folder of lander fly, demo or campaign)")


def _has_display() -> bool:
    """Whether a graphical browser can open here (on Linux a terminal over ssh has none, and
    webbrowser would fall back to a text browser in this terminal)."""
    return sys.platform in ("darwin", "win32") or bool(
        os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY"))


def run(args: argparse.Namespace) -> int:
    page = find_page(Path(args.out_dir))
    if not args.print and _has_display() and webbrowser.open(page.resolve().as_uri()):
        print(f"opened {page}")
    else:
        print(page)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "replay", help="open a flight's report.html (or a campaign's page) in a browser",
        description="Open OUT_DIR/report.html, the page of a flight written by lander fly or "
        "lander demo (or OUT_DIR/campaign.html of lander campaign), in the default web "
        "browser; prints its path with --print or when there is no display (DISPLAY, "
        "WAYLAND_DISPLAY) or browser. The page is one "
        "file and needs no server or network.",
    )
    parser.add_argument("out_dir", metavar="OUT_DIR", help="the flight's report folder")
    parser.add_argument("--print", action="store_true",
                        help="print the page's path instead of opening a browser")
    parser.set_defaults(func=run)
