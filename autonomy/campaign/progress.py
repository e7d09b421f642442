"""The live progress line of a campaign on stderr.

On a terminal the line is rewritten in place (``\\r``); otherwise (a log file, CI) a plain
line is printed every 5 % of the runs and at the end.
"""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

from autonomy.campaign.stats import wilson_interval
from autonomy.campaign.summary import is_success, outcome_class


class Progress:
    """Counts finished runs and shows the running success rate with its Wilson interval."""

    def __init__(self, total: int, stream: TextIO | None = None, label: str = "campaign") -> None:
        self.total = total
        self.stream = stream if stream is not None else sys.stderr
        self.label = label
        self.done = self.landed = self.errors = 0
        self._tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self._every = max(1, total // 20)
        self._start = time.monotonic()

    def line(self) -> str:
        """The current progress text."""
        flown = self.done - self.errors
        text = f"{self.label}: {self.done}/{self.total} runs"
        if flown:
            low, high = wilson_interval(self.landed, flown)
            text += (f", success {100 * self.landed / flown:.1f}% "
                     f"[{100 * low:.1f}, {100 * high:.1f}]")
        if self.errors:
            text += f", {self.errors} error{'s' if self.errors > 1 else ''}"
        elapsed = time.monotonic() - self._start
        text += f", {elapsed:.0f} s"
        if 0 < self.done < self.total:
            text += f", ~{elapsed / self.done * (self.total - self.done):.0f} s left"
        return text

    def update(self, record: dict[str, Any]) -> None:
        """Count one finished run and refresh the display."""
        self.done += 1
        self.landed += is_success(record)
        self.errors += outcome_class(record) == "error"
        if self._tty:
            self.stream.write("\r" + self.line() + "\x1b[K")
            if self.done == self.total:
                self.stream.write("\n")
        elif self.done % self._every == 0 or self.done == self.total:
            self.stream.write(self.line() + "\n")
        self.stream.flush()
