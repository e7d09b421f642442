""""Did you mean": the registered name nearest a mistyped one (difflib), for the one-line
refusals of mission files (their settings) and tree files (their nodes). Here rather than in
``autonomy`` so that ``behaviors`` can use it too."""

from __future__ import annotations

import difflib
from collections.abc import Iterable


def did_you_mean(word: str, names: Iterable[str], cutoff: float = 0.75) -> str:
    """``"; did you mean NAME?"`` when ``word`` looks like a typo of one of ``names``, else
    ``""``."""
    close = difflib.get_close_matches(word, sorted(names), n=1, cutoff=cutoff)
    return f"; did you mean {close[0]}?" if close else ""
