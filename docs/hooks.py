"""MkDocs hook: the site's home page is README.md, so the two never drift apart.

docs/index.md is a placeholder; its text is replaced by the README's, with links made
relative to docs/ (README links read ``docs/tutorials/x.md``, the site ``tutorials/x.md``).
"""

from __future__ import annotations

import re
from pathlib import Path

_README = Path(__file__).resolve().parents[1] / "README.md"


def on_page_markdown(markdown: str, page, config, files) -> str:
    if page.file.src_uri != "index.md":
        return markdown
    text = _README.read_text(encoding="utf-8")
    text = re.sub(r"\]\(docs/", "](", text)
    return text
