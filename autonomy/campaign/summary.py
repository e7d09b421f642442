"""Per-variant tables of campaign outcomes, and paired comparisons of missions.

Outcome classes: ``landed`` (safe touchdown), ``landed_unsafe``, ``crashed``, ``no_site``,
``failsafe`` (a failsafe landed the vehicle wherever it was: not a success, even on safe
ground), ``aborted``, and ``error`` (the run raised or its worker died). The success rate is
landed-safe runs over runs that flew (errors excluded: they say nothing about the landing
procedure), with its Wilson 95 % interval; time-to-land statistics are over landed runs.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from autonomy.campaign.spec import Variant
from autonomy.campaign.stats import newcombe_paired_interval, wilson_interval
from autonomy.report.summary import OUTCOMES as FLIGHT_OUTCOMES

# Campaigns fly lockstep: the outcomes only a live flight has get no column.
_LIVE_ONLY = ("landed_unjudged", "link_lost", "refused")
OUTCOMES: tuple[str, ...] = (*(o for o in FLIGHT_OUTCOMES if o not in _LIVE_ONLY), "error")
OUTCOME_TITLES: dict[str, str] = {
    "landed": "landed safe",
    "landed_unsafe": "landed unsafe",
    "crashed": "crashed",
    "no_site": "no site",
    "failsafe": "failsafe landing",
    "aborted": "aborted",
    "error": "error",
}


def outcome_class(record: dict[str, Any]) -> str:
    """The outcome column a run counts in (a ``landed`` run judged unsafe is unsafe)."""
    outcome = record.get("outcome")
    if outcome == "landed" and record.get("touchdown_safe") is False:
        return "landed_unsafe"
    return outcome if outcome in OUTCOMES else "aborted"


def is_success(record: dict[str, Any]) -> bool:
    """A safe landing."""
    return outcome_class(record) == "landed"


def _none_if_nan(x: float) -> float | None:
    return None if x is None or math.isnan(x) else float(x)


def is_unsafe_touchdown(record: dict[str, Any]) -> bool:
    """The vehicle touched ground the ground truth calls unsafe, whatever the outcome (a
    landing at a site, or a landing in place after no site could be verified)."""
    return record.get("touchdown_safe") is False and outcome_class(record) != "error"


def summarise(records: Iterable[dict[str, Any]], variant: Variant | None = None) -> dict:
    """Counts, unsafe touchdowns, collisions, success rate with Wilson 95 % interval, median
    and p90 time to land."""
    records = list(records)
    counts = dict.fromkeys(OUTCOMES, 0)
    for record in records:
        counts[outcome_class(record)] += 1
    unsafe_touchdowns = sum(is_unsafe_touchdown(r) for r in records)
    flown = len(records) - counts["error"]
    low, high = wilson_interval(counts["landed"], flown)
    times = np.array(
        [r["time_to_land"] for r in records
         if outcome_class(r) in ("landed", "landed_unsafe") and r.get("time_to_land") is not None],
        dtype=float,
    )
    median, p90 = (np.percentile(times, [50, 90]) if times.size else (math.nan, math.nan))
    row: dict[str, Any] = {}
    if variant is not None:
        row.update(variant=variant.index, label=variant.label, values=dict(variant.overrides))
    row.update(
        runs=len(records),
        **counts,
        unsafe_touchdowns=unsafe_touchdowns,
        # contacts with raised ground or moving obstacles (sitl.terrain.contact), all runs
        collisions=sum(int(r.get("collisions") or 0) for r in records),
        success_rate=_none_if_nan(counts["landed"] / flown if flown else math.nan),
        success_low=_none_if_nan(low),
        success_high=_none_if_nan(high),
        time_to_land_median=_none_if_nan(median),
        time_to_land_p90=_none_if_nan(p90),
    )
    return row


def summarise_variants(
    records: Sequence[dict[str, Any]], variants: Sequence[Variant]
) -> list[dict[str, Any]]:
    """One :func:`summarise` row per variant, in variant order."""
    by_key: dict[str, list[dict[str, Any]]] = {v.key: [] for v in variants}
    for record in records:
        by_key.setdefault(record["variant_key"], []).append(record)
    return [summarise(by_key[v.key], v) for v in variants]


def _pct(x: float | None) -> str:
    return "-" if x is None else f"{100 * x:.1f}"


def _sec(x: float | None) -> str:
    return "-" if x is None else f"{x:.1f}"


def text_table(head: Sequence[str], lines: Sequence[Sequence[str]]) -> str:
    """Fixed-width columns: the first left-aligned, the others right-aligned."""
    widths = [max(len(h), *(len(line[i]) for line in lines)) for i, h in enumerate(head)]

    def row(cells: Sequence[str]) -> str:
        first, *rest = (
            c.ljust(w) if i == 0 else c.rjust(w)
            for i, (c, w) in enumerate(zip(cells, widths, strict=True))
        )
        return "  ".join([first, *rest])

    return "\n".join([row(head), *(row(line) for line in lines)])


def _interval(low: float | None, high: float | None) -> str:
    return f"[{_pct(low)}, {_pct(high)}]"


def format_table(rows: Sequence[dict[str, Any]]) -> str:
    """A text table of :func:`summarise` rows: counts per outcome, unsafe touchdowns (of
    any outcome, e.g. a landing in place on rocks), collisions (all runs), success rate (%)
    with its Wilson 95 % interval, median and 90th percentile time to land (sim s)."""
    head = ["variant", "runs", *(OUTCOME_TITLES[o] for o in OUTCOMES), "unsafe touchdowns",
            "collisions", "success %", "95% CI", "TTL median s", "TTL p90 s"]
    lines = [
        [row.get("label", "all"), str(row["runs"]), *(str(row[o]) for o in OUTCOMES),
         str(row.get("unsafe_touchdowns", "-")), str(row.get("collisions", "-")),
         _pct(row["success_rate"]),
         _interval(row["success_low"], row["success_high"]),
         _sec(row["time_to_land_median"]), _sec(row["time_to_land_p90"])]
        for row in rows
    ]
    return text_table(head, lines)


def compare_missions(
    names: Sequence[str], records: Sequence[Sequence[dict[str, Any]]]
) -> list[dict[str, Any]]:
    """Each mission against the first one, paired by seed.

    Pairs where either run is an ``error`` are left out. ``difference`` is
    ``success(mission) - success(baseline)`` over the pairs, with Newcombe's paired hybrid
    score 95 % interval; ``unsafe`` counts unsafe touchdowns (any outcome) over all runs of
    the mission.
    """
    base = {r["seed"]: r for r in records[0]}
    rows = []
    for name, mission_records in zip(names, records, strict=True):
        table = {"both": 0, "only_mission": 0, "only_baseline": 0, "neither": 0}
        for record in mission_records:
            other = base.get(record["seed"])
            if other is None or "error" in (outcome_class(record), outcome_class(other)):
                continue
            mine, theirs = is_success(record), is_success(other)
            key = ("both" if theirs else "only_mission") if mine else (
                "only_baseline" if theirs else "neither")
            table[key] += 1
        pairs = sum(table.values())
        low, high = newcombe_paired_interval(
            table["both"], table["only_mission"], table["only_baseline"], table["neither"]
        )
        rows.append({
            "mission": name,
            **summarise(mission_records),
            "unsafe": sum(is_unsafe_touchdown(r) for r in mission_records),
            "pairs": pairs,
            **table,
            "difference": (table["only_mission"] - table["only_baseline"]) / pairs
            if pairs else None,
            "difference_low": _none_if_nan(low),
            "difference_high": _none_if_nan(high),
        })
    return rows


def format_comparison(rows: Sequence[dict[str, Any]]) -> str:
    """A text table of :func:`compare_missions` rows (the first row is the baseline);
    differences are in percentage points with Newcombe's paired 95 % interval."""
    head = ["mission", "runs", "success %", "95% CI", "unsafe", "error",
            f"diff vs {rows[0]['mission']} (pp)", "95% CI (pp)"]
    lines = []
    for i, row in enumerate(rows):
        if i == 0:
            diff, ci = "baseline", ""
        elif row["difference"] is None:
            diff, ci = "-", "-"
        else:
            diff = f"{100 * row['difference']:+.1f}"
            ci = f"[{100 * row['difference_low']:+.1f}, {100 * row['difference_high']:+.1f}]"
        lines.append([row["mission"], str(row["runs"]), _pct(row["success_rate"]),
                      _interval(row["success_low"], row["success_high"]),
                      str(row["unsafe"]), str(row["error"]), diff, ci])
    return text_table(head, lines)
