"""``lander replay OUT_DIR``: open a flight's report.html (or a campaign's campaign.html).

    lander replay out/demo            # opens out/demo/report.html in the default browser
    lander replay out/demo --print    # prints its path instead (no browser, e.g. over ssh)
"""

from __future__ import annotations

import argparse
import webbrowser
from pathlib import Path

from autonomy.errors import UserError

PAGES = ("report.html", "campaign.html")


def find_page(folder: Path) -> Path:
    """The report page of ``folder`` (a flight's report.html, else a campaign's
    campaign.html); raises :class:`UserError` saying what is missing."""
    if not folder.exists():
        raise UserError(f"{folder}: no such folder")
    if not folder.is_dir():
        raise UserError(f"{folder}: not a folder (give the output folder of lander fly, demo "
                        "or campaign)")
    for name in PAGES:
        if (folder / name).is_file():
            return folder / name
    has_logs = [p for p in ("events.jsonl", "summary.json", "tree.btlog") if (folder / p).exists()]
    why = (f"it holds {', '.join(has_logs)} but no report.html (the flight was written before "
           "reports had pages, or did not finish)") if has_logs else (
        "no report.html or campaign.html (not the output folder of lander fly, demo or "
        "campaign)")
    raise UserError(f"{folder}: {why}")


def run(args: argparse.Namespace) -> int:
    page = find_page(Path(args.out_dir))
    if not args.print and webbrowser.open(page.resolve().as_uri()):
        print(f"opened {page}")
    else:
        print(page)
    return 0


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        "replay", help="open a flight's report.html (or a campaign's page) in a browser",
        description="Open OUT_DIR/report.html, the page of a flight written by lander fly or "
        "lander demo (or OUT_DIR/campaign.html of lander campaign), in the default web "
        "browser; prints its path when there is no browser or with --print. The page is one "
        "file and needs no server or network.",
    )
    parser.add_argument("out_dir", metavar="OUT_DIR", help="the flight's report folder")
    parser.add_argument("--print", action="store_true",
                        help="print the page's path instead of opening a browser")
    parser.set_defaults(func=run)
