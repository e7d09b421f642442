"""``runs.jsonl``: the campaign's append-only record of finished runs, one JSON object a line.

Each run is appended (and flushed to disk) as soon as it finishes, so an interrupted campaign
loses nothing it has flown; re-running the same command reads the file and skips those runs.
A half-written last line (the process was killed while writing) is ignored.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from autonomy.errors import UserError

RUNS_FILE = "runs.jsonl"


class RunLog:
    """The ``runs.jsonl`` of one output directory."""

    def __init__(self, out_dir: str | os.PathLike[str]) -> None:
        self.path = Path(out_dir) / RUNS_FILE
        self.skipped_lines = 0

    def load(self) -> list[dict[str, Any]]:
        """Every complete record in file order (``[]`` if there is no file yet)."""
        if not self.path.exists():
            return []
        records = []
        self.skipped_lines = 0
        with self.path.open(encoding="utf-8") as stream:
            for line in stream:
                try:
                    record = json.loads(line)
                except json.JSONDecodeError:
                    self.skipped_lines += 1
                    continue
                if isinstance(record, dict) and "run_id" in record:
                    records.append(record)
                else:
                    self.skipped_lines += 1
        return records

    def latest(self) -> dict[tuple[str, str, int], dict[str, Any]]:
        """The last record of each (mission, variant key, seed): what resuming goes by."""
        return {
            (r.get("mission"), r.get("variant_key"), r.get("seed")): r for r in self.load()
        }

    def append(self, record: dict[str, Any]) -> None:
        """Write one record as a line and push it to disk before returning."""
        self.path.parent.mkdir(parents=True, exist_ok=True)
        line = json.dumps(record, sort_keys=True, allow_nan=False) + "\n"
        with self.path.open("a", encoding="utf-8") as stream:
            stream.write(line)
            stream.flush()
            os.fsync(stream.fileno())

    def check_mission(self, mission_id: str) -> None:
        """Refuse an output directory that holds runs of a different mission."""
        others = {r.get("mission") for r in self.load()} - {mission_id}
        if others:
            raise UserError(
                f"{self.path}: holds runs of a different mission (or mission file version); "
                "choose another --out or remove the file"
            )
