"""``campaign.html``: a campaign in the browser, one self-contained file.

The outcomes per variant (counts as a stacked bar, success rate with its Wilson 95 %
interval, time to land), campaign.png inline, and every run with its seed, outcome and
figures, linked to its own flight page (``runs/<run id>/report.html``) when the run wrote
one. No script, no network: a static page any browser opens from disk.
"""

from __future__ import annotations

import base64
import html
from pathlib import Path
from typing import Any

from autonomy.campaign.plot import OUTCOME_COLOURS
from autonomy.campaign.summary import OUTCOME_TITLES, OUTCOMES, outcome_class

PAGE_FILE = "campaign.html"

_STYLE = """
body { font: 13px/1.4 system-ui, sans-serif; margin: 0; color: #222; background: #f6f6f4; }
header { padding: 10px 16px; background: #24303c; color: #eee; }
h1 { font-size: 18px; margin: 0 0 4px 0; } h2 { font-size: 15px; margin: 16px 0 6px 0; }
main { padding: 4px 16px 16px; }
table { border-collapse: collapse; background: #fff; }
th, td { border: 1px solid #ddd; padding: 3px 8px; text-align: right; white-space: nowrap; }
th { background: #eef1f4; } td.label, th.label { text-align: left; }
.bar { display: flex; width: 260px; height: 14px; border: 1px solid #999; }
.bar span { display: block; height: 100%; }
.outcome { display: inline-block; padding: 0 6px; border-radius: 3px; color: #fff; }
img { max-width: 100%; border: 1px solid #ddd; background: #fff; }
.scroll { overflow-x: auto; }
.legend span { margin-right: 12px; } .legend i { display: inline-block; width: 10px;
  height: 10px; margin-right: 4px; }
"""


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f}"


def _num(x: Any, digits: int = 1) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def _bar(row: dict[str, Any]) -> str:
    total = max(1, row["runs"])
    parts = "".join(
        f'<span style="width:{100 * row[o] / total:.2f}%;background:{OUTCOME_COLOURS[o]}" '
        f'title="{OUTCOME_TITLES[o]}: {row[o]}"></span>'
        for o in OUTCOMES if row[o]
    )
    return f'<div class="bar">{parts}</div>'


def _variants_table(rows: list[dict[str, Any]]) -> str:
    head = "".join(f"<th>{html.escape(OUTCOME_TITLES[o])}</th>" for o in OUTCOMES)
    lines = [
        "<table><tr><th class=label>variant</th><th>runs</th><th class=label>outcomes</th>"
        f"{head}<th>success %</th><th>95% CI</th><th>TTL median s</th><th>TTL p90 s</th></tr>"
    ]
    for row in rows:
        cells = "".join(f"<td>{row[o]}</td>" for o in OUTCOMES)
        lines.append(
            f"<tr><td class=label>{html.escape(str(row.get('label', 'all')))}</td>"
            f"<td>{row['runs']}</td><td class=label>{_bar(row)}</td>{cells}"
            f"<td>{_pct(row['success_rate'])}</td>"
            f"<td>[{_pct(row['success_low'])}, {_pct(row['success_high'])}]</td>"
            f"<td>{_num(row['time_to_land_median'])}</td>"
            f"<td>{_num(row['time_to_land_p90'])}</td></tr>"
        )
    lines.append("</table>")
    return "\n".join(lines)


def _runs_table(records: list[dict[str, Any]], out_dir: Path, runs_dir: str) -> str:
    lines = [
        "<table><tr><th class=label>run</th><th class=label>variant</th><th>seed</th>"
        "<th class=label>outcome</th><th>time to land s</th><th>touchdown error m</th>"
        "<th>battery used %</th><th>sites verified / banned</th>"
        "<th class=label>flight page</th></tr>"
    ]
    for r in records:
        outcome = outcome_class(r)
        page = Path(runs_dir) / str(r["run_id"]) / "report.html"
        link = (f'<a href="{html.escape(page.as_posix())}">report.html</a>'
                if (out_dir / page).is_file() else "-")
        why = r.get("outcome_hint") or r.get("failure_reason") or r.get("crash_reason") or ""
        lines.append(
            f"<tr><td class=label>{html.escape(str(r['run_id']))}</td>"
            f"<td class=label>{html.escape(str(r.get('variant_label') or 'all'))}</td>"
            f"<td>{r.get('seed')}</td><td class=label><span class=outcome "
            f"style=\"background:{OUTCOME_COLOURS[outcome]}\" title=\"{html.escape(str(why))}\">"
            f"{html.escape(OUTCOME_TITLES[outcome])}</span></td>"
            f"<td>{_num(r.get('time_to_land'))}</td><td>{_num(r.get('touchdown_error'), 2)}</td>"
            f"<td>{_num(r.get('battery_used'))}</td>"
            f"<td>{r.get('sites_verified', '-')} / {r.get('sites_banned', '-')}</td>"
            f"<td class=label>{link}</td></tr>"
        )
    lines.append("</table>")
    return "\n".join(lines)


def render_campaign_html(result: Any, runs_dir: str = "runs") -> str:
    """The page of a :class:`autonomy.campaign.engine.CampaignResult`."""
    meta = result.meta
    name = meta.get("name") or "campaign"
    plot = result.out_dir / "campaign.png"
    image = ""
    if plot.is_file():
        data = base64.b64encode(plot.read_bytes()).decode()
        image = f'<h2>Overview</h2><img alt="campaign.png" src="data:image/png;base64,{data}">'
    vary = "; ".join(f"{k} = {', '.join(map(str, v))}" for k, v in meta.get("vary", {}).items())
    legend = "".join(f'<span><i style="background:{OUTCOME_COLOURS[o]}"></i>'
                     f"{html.escape(OUTCOME_TITLES[o])}</span>" for o in OUTCOMES)
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(name)}: campaign</title>
<style>{_STYLE}</style></head>
<body><header><h1>{html.escape(name)}: {len(result.records)} runs</h1>
<div>seed {meta.get('seed')}, {meta.get('runs')} run(s) per variant{
    ', varied: ' + html.escape(vary) if vary else ''}; mission {
    html.escape(str(meta.get('mission')))}</div></header>
<main>
<h2>Outcomes per variant</h2>
<div class="legend">{legend}</div>
<div class="scroll">{_variants_table(result.rows)}</div>
{image}
<h2>Runs</h2>
<div class="scroll">{_runs_table(result.records, result.out_dir, runs_dir)}</div>
</main></body></html>
"""


def write_campaign_html(result: Any, path: Path, runs_dir: str = "runs") -> None:
    """Write :func:`render_campaign_html` to ``path``."""
    Path(path).write_text(render_campaign_html(result, runs_dir), encoding="utf-8")
