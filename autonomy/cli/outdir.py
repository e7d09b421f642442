"""Output folders of ``lander fly``/``demo`` and ``lander campaign``: a command writes into a
folder only when nothing there belongs to something else.

A flight's report and a campaign share file names (``summary.json``), so flying into a
campaign's folder (or running a campaign in a flight's) would silently replace the other's
results. A folder that already holds the same command's output is written again, as the
user expects from re-running a command.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from autonomy.cli import FULL_OR_READ_ONLY
from autonomy.errors import UserError

FLIGHT_FILES = ("summary.json", "events.jsonl", "flight.tlog", "report.png", "report.html",
                "tree.btlog", "blackboard.jsonl")
CAMPAIGN_FILES = ("summary.json", "campaign.png", "campaign.html")
CAMPAIGN_RECORD = "runs.jsonl"


def _summary_keys(path: Path) -> set[str] | None:
    """The top-level keys of a summary.json, or None when it is not a JSON object."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return set(data) if isinstance(data, dict) else None


def _must_be_folder(flag: str, out: Path) -> bool:
    """Whether ``out`` exists (as a folder); refuses anything else that exists there."""
    if out.is_dir():
        return True
    if out.exists() or out.is_symlink():
        raise UserError(f"{flag} {out}: exists and is not a folder")
    return False


def check_flight_folder(out: Path, flag: str = "--out") -> None:
    """Refuse a report folder whose files a flight's report would replace but which are not
    a flight's: a campaign's folder, or files of the same names from elsewhere."""
    if not _must_be_folder(flag, out):
        return
    if (out / CAMPAIGN_RECORD).exists():
        raise UserError(f"{flag} {out}: holds a campaign ({CAMPAIGN_RECORD}); a flight's "
                        "report would replace its summary.json; choose another folder")
    summary = out / "summary.json"
    keys = _summary_keys(summary) if summary.exists() else None
    if (keys and "outcome" in keys) or (not summary.exists()
                                         and (out / "events.jsonl").is_file()):
        return  # an earlier flight's report (or the logs of one killed before its report)
    clash = next((name for name in FLIGHT_FILES if (out / name).exists()), None)
    if clash is not None:
        raise UserError(f"{flag} {out}: holds {clash}, not from a flight, which the report "
                        "would replace; choose another folder or remove it")


def check_campaign_folder(out: Path, flag: str = "--out") -> None:
    """Refuse a campaign folder whose files the campaign's would replace but which are not a
    campaign's (a flight's report above all)."""
    if not _must_be_folder(flag, out):
        return
    if (out / CAMPAIGN_RECORD).exists():
        return  # a campaign's: its runs.jsonl decides whether the mission matches
    summary = out / "summary.json"
    keys = _summary_keys(summary) if summary.exists() else None
    if keys and "variants" in keys:
        return  # a campaign's summary whose runs.jsonl was removed: written again
    if keys and "outcome" in keys:
        raise UserError(f"{flag} {out}: holds a flight's report (summary.json); the "
                        "campaign's would replace it; choose another folder")
    clash = next((name for name in CAMPAIGN_FILES if (out / name).exists()), None)
    if clash is not None:
        raise UserError(f"{flag} {out}: holds {clash}, not from a campaign, which the "
                        "campaign would replace; choose another folder or remove it")


@contextmanager
def writing_into(folder: Path, what: str) -> Iterator[None]:
    """Say which folder a full or read-only disk stopped ``what`` being written into (the
    error itself often names no file: a buffered write fails when the file is closed)."""
    try:
        yield
    except OSError as exc:
        if exc.errno not in FULL_OR_READ_ONLY:
            raise
        raise UserError(f"{folder}: cannot write {what} ({exc.strerror or exc}); what is "
                        "there may be incomplete") from None
