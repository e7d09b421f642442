"""report.html: one self-contained page per flight (no server, no network).

The page embeds the flight as JSON (:func:`autonomy.report.page.build_page`) and a small
viewer (viewer.js, viewer.css beside this module) that draws it with plain SVG.
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

REPORT_HTML = "report.html"

_PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{title}</title>
<style>
{css}</style>
</head>
<body>
<header>
<h1>{heading} <span id="outcome" class="badge"></span></h1>
<div class="facts" id="facts"></div>
</header>
<div id="controls">
<button id="play" type="button">play</button>
<input id="slider" type="range" min="0" max="1" step="0.1" value="0"
 aria-label="time in the flight">
<div id="readout"></div>
</div>
<main>
<section id="map-panel">
<h2>Map (east/north, m)</h2>
<svg id="map" role="img" aria-label="map of the flight"></svg>
<div class="legend" id="map-legend"></div>
</section>
<section id="time-panel">
<h2>Altitude, battery, detector events and the tree, in step</h2>
<svg id="alt"></svg>
<svg id="batt"></svg>
<svg id="events"></svg>
<h2>Tree timeline <small id="tree-source"></small></h2>
<div id="tree-wrap"><svg id="tree"></svg></div>
</section>
</main>
<footer>{footer}</footer>
<div id="tip"></div>
<script id="flight-data" type="application/json">{data}</script>
<script>
{js}</script>
</body>
</html>
"""


def _asset(name: str) -> str:
    return resources.files("autonomy.report").joinpath(name).read_text(encoding="utf-8")


def render_html(page: dict[str, Any], footer: str = "") -> str:
    """The report page for ``page`` (the dict of :func:`build_page`)."""
    summary = page.get("summary", {})
    name = summary.get("mission") or "mission"
    # No "<" at all in the data script ("</script>", "<!--" cannot end or bend it); JSON
    # reads the escape back as "<".
    data = json.dumps(page, separators=(",", ":"), allow_nan=False).replace("<", "\\u003c")
    return _PAGE.format(
        title=html.escape(f"{name}: {summary.get('outcome', '')} (seed {summary.get('seed')})"),
        heading=html.escape(f"{name} \u2014 seed {summary.get('seed')}"),
        css=_asset("viewer.css"), js=_asset("viewer.js"), data=data,
        footer=html.escape(footer),
    )


def write_report_html(page: dict[str, Any], path: Path, footer: str = "") -> None:
    """Write :func:`render_html` to ``path``."""
    Path(path).write_text(render_html(page, footer), encoding="utf-8")


def write_flight_page(data: Any, summary: dict[str, Any], events: Sequence[dict[str, Any]],
                      out_dir: Path) -> Path:
    """Write ``out_dir/report.html`` of a flight (its tree timeline from ``out_dir``'s
    tree.btlog when the flight wrote one); returns its path."""
    from autonomy.report.page import build_page

    out_dir = Path(out_dir)
    files = [p for p in ("summary.json", "events.jsonl", "flight.tlog", "tree.btlog",
                         "blackboard.jsonl", "report.png") if (out_dir / p).exists()]
    footer = f"Files beside this page: {', '.join(files)}." if files else ""
    path = out_dir / REPORT_HTML
    write_report_html(build_page(data, summary, events, out_dir), path, footer)
    return path
