"""Running a campaign: plan, skip what is recorded, fly the rest, summarise, plot.

    from autonomy.config import load_mission
    from autonomy.campaign import run_campaign

    if __name__ == "__main__":  # worker processes import this script: run only once
        result = run_campaign(load_mission("missions/demo.yaml"), runs=20, seed=1,
                              vary=["landing.verification_altitude=2.5,5"], out_dir="out/demo")
        print(result.table())

A run whose worker process dies (the OOM killer's SIGKILL, a segmentation fault) is flown
once more alone; if its worker dies again it is recorded as ``error`` with ``worker_died``
(the signal, e.g. ``"SIGKILL"``), the other runs go on, and re-running the campaign flies it
again (see :class:`autonomy.campaign.backends.LocalPool`).

Output directory: ``runs.jsonl`` (one record per finished run, appended as runs finish),
``summary.json`` (per-variant table), ``campaign.png``, ``campaign.html`` (outcomes per
variant, each run linked to its flight page) and ``runs/<run id>/`` (each run's report.html
and logs).
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, TextIO

from autonomy.campaign.backends import Backend, make_backend
from autonomy.campaign.page import PAGE_FILE, write_campaign_html
from autonomy.campaign.plan import (
    FlightFunction,
    OverrideFunction,
    RunTask,
    mission_digest,
    plan,
)
from autonomy.campaign.plot import plot_campaign, representative_terrain
from autonomy.campaign.progress import Progress
from autonomy.campaign.spec import Variant, Vary, parse_vary, variants
from autonomy.campaign.store import RunLog
from autonomy.campaign.summary import (
    compare_missions,
    format_comparison,
    format_table,
    summarise_variants,
)
from autonomy.errors import UserError

SUMMARY_FILE = "summary.json"
PLOT_FILE = "campaign.png"
RUNS_DIR = "runs"  # runs/<run id>/: each run's report folder and flight page
COMPARE_FILE = "compare.json"


@dataclass
class CampaignResult:
    """What a campaign produced.

    ``records`` holds one run record per planned run, in plan order (variant-major), whether
    flown now or found in ``runs.jsonl``; ``rows`` one summary row per variant.
    """

    out_dir: Path
    variants: list[Variant]
    records: list[dict[str, Any]]
    rows: list[dict[str, Any]]
    flown: int
    skipped: int
    meta: dict[str, Any] = field(default_factory=dict)

    def table(self) -> str:
        """The per-variant summary table as text."""
        return format_table(self.rows)

    def died(self) -> list[dict[str, Any]]:
        """Records of the runs whose worker process died under them (twice, the second time
        alone): ``error`` runs that re-running the campaign flies again."""
        return [r for r in self.records if r.get("worker_died")]

    def throughput_line(self) -> str | None:
        """The simulated flight-hours per wall-clock hour of the runs flown by this call,
        or None when none was flown (all recorded already)."""
        t = self.meta.get("throughput")
        if not t:
            return None
        return (
            f"throughput: {t['simulated_s'] / 3600:.2f} simulated flight-h in "
            f"{t['wall_s'] / 3600:.3f} wall-h on {t['workers']} worker(s): "
            f"{t['flight_h_per_wall_h']:.1f} flight-h per wall-h, "
            f"{t['flight_h_per_wall_h_per_worker']:.1f} per worker"
        )


def throughput(flown: Sequence[dict[str, Any]], wall_s: float, workers: int) -> dict | None:
    """Simulated flight time over wall time of ``flown`` records, in total and per worker.

    The simulated time of a run is its ``mission_time`` (take-off to the end of the flight);
    runs without one (errors) add wall time but no flight time.
    """
    if not flown or wall_s <= 0:
        return None
    simulated = sum(float(r.get("mission_time") or 0.0) for r in flown)
    rate = simulated / wall_s
    return {
        "runs": len(flown),
        "simulated_s": round(simulated, 1),
        "wall_s": round(wall_s, 3),
        "workers": workers,
        "flight_h_per_wall_h": round(rate, 2),
        "flight_h_per_wall_h_per_worker": round(rate / max(1, workers), 2),
    }


def _default_flight() -> FlightFunction:
    from autonomy.campaign.worker import fly_with_page

    return fly_with_page


def _default_apply() -> OverrideFunction:
    from autonomy.config import apply_overrides

    return apply_overrides


def prepare(
    mission: Any,
    *,
    runs: int,
    seed: int = 0,
    vary: Sequence[str | Vary] = (),
    flight: FlightFunction | None = None,
    apply_overrides: OverrideFunction | None = None,
) -> tuple[list[Variant], list[RunTask]]:
    """Validate the options and plan every run; raises :class:`UserError` on bad input
    (a malformed SPEC, a key the mission schema lacks, a value it rejects)."""
    if runs < 1:
        raise UserError(f"--runs {runs}: must be at least 1")
    if seed < 0:
        raise UserError(f"--seed {seed}: must be >= 0")
    parsed = [v if isinstance(v, Vary) else parse_vary(v) for v in vary]
    chosen = variants(parsed)
    if parsed and apply_overrides is None:
        apply_overrides = _default_apply()
    if parsed:
        # Check each key alone first, so that the message names the key at fault.
        for v in parsed:
            _apply(apply_overrides, mission, {v.key: v.values[0]})
    tasks = plan(
        mission,
        chosen,
        runs,
        seed,
        flight or _default_flight(),
        (lambda m, o: _apply(apply_overrides, m, o)) if parsed else None,
    )
    return chosen, tasks


def _apply(apply_overrides: OverrideFunction, mission: Any, overrides: dict[str, Any]) -> Any:
    try:
        return apply_overrides(mission, overrides)
    except UserError as exc:
        raise UserError(f"--vary: {exc}") from None
    except ValueError as exc:  # pydantic's ValidationError is a ValueError
        shown = ", ".join(f"{k}={v}" for k, v in overrides.items())
        raise UserError(f"--vary {shown}: {' '.join(str(exc).split())}") from None


def run_campaign(
    mission: Any,
    *,
    runs: int,
    out_dir: str | os.PathLike[str],
    seed: int = 0,
    vary: Sequence[str | Vary] = (),
    workers: int | None = None,
    scheduler: str | None = None,
    connect_timeout: float = 10.0,
    backend: Backend | None = None,
    flight: FlightFunction | None = None,
    apply_overrides: OverrideFunction | None = None,
    retry_errors: bool = False,
    progress: TextIO | None = None,
    quiet: bool = False,
    name: str = "",
    pages: bool = True,
) -> CampaignResult:
    """Fly ``runs`` seeded flights of ``mission`` per variant and write the results.

    Args:
        mission: an :class:`autonomy.config.Mission`.
        runs: flights per variant; run ``i`` of every variant uses the same seed.
        out_dir: where ``runs.jsonl``, ``summary.json`` and ``campaign.png`` go.
        seed: campaign seed the per-run seeds derive from (see :func:`plan.run_seed`).
        vary: ``KEY=SPEC`` strings (see :mod:`autonomy.campaign.spec`) or :class:`Vary`.
        workers: local pool size (default: the cores), or workers of ``scheduler="local"``.
        scheduler: ``tcp://HOST:PORT`` of a Dask scheduler, or ``"local"``; None: local pool.
        connect_timeout: seconds to wait for the scheduler before giving up.
        backend: an already made backend (overrides ``workers`` and ``scheduler``).
        flight: the flight function (default :func:`autonomy.runner.fly`); a top-level
            function, since worker processes unpickle it by reference.
        apply_overrides: default :func:`autonomy.config.apply_overrides`.
        retry_errors: fly again the runs recorded as ``error`` (default: skip them too,
            except runs whose worker process died, which are always flown again).
        progress: stream for the progress line (default stderr); ``quiet`` silences it.
        name: title of the plot.
        pages: each run writes its report folder ``runs/<run id>/`` (report.html and its
            logs) for campaign.html to link to; on a Dask cluster the workers must see
            ``out_dir`` (a shared folder).

    Raises:
        UserError: bad options, an output directory holding another mission's runs, or an
            unreachable scheduler, all before any run starts.
    """
    chosen, tasks = prepare(
        mission, runs=runs, seed=seed, vary=vary, flight=flight, apply_overrides=apply_overrides
    )
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise UserError(f"--out {out}: exists and is not a directory")
    if pages:
        runs_dir = out.resolve() / RUNS_DIR
        tasks = [replace(t, out_dir=str(runs_dir / t.run_id)) for t in tasks]
    log = RunLog(out)
    log.check_mission(mission_digest(mission))
    recorded = log.latest()
    todo = [
        t for t in tasks
        if t.identity not in recorded
        or recorded[t.identity].get("worker_died")  # not a result: flown again
        or (retry_errors and recorded[t.identity].get("outcome") == "error")
    ]
    own_backend = None
    if todo and backend is None:  # made before anything is written: it may refuse
        backend = own_backend = make_backend(workers, scheduler, connect_timeout)
    out.mkdir(parents=True, exist_ok=True)
    flown: list[dict[str, Any]] = []
    started = time.monotonic()  # wall time of the flights, for the throughput figure
    try:
        meter = None if quiet else Progress(len(todo), progress, label=name or "campaign")
        for record in backend.run(todo) if todo else ():
            flown.append(record)
            log.append(record)
            recorded[(record["mission"], record["variant_key"], record["seed"])] = record
            if meter is not None:
                meter.update(record)
    finally:
        if own_backend is not None:
            own_backend.close()
    busy_workers = min(getattr(backend, "workers", 1), len(todo)) if todo else 1
    records = [recorded[t.identity] for t in tasks]
    rows = summarise_variants(records, chosen)
    meta = {
        "name": name,
        "mission": mission_digest(mission),
        "seed": seed,
        "runs": runs,
        "vary": {k: list(v) for k, v in _varied(chosen).items()},
        "seeds": [t.seed for t in tasks[:runs]],
        "throughput": throughput(flown, time.monotonic() - started, busy_workers),
    }
    result = CampaignResult(out, chosen, records, rows, len(todo), len(tasks) - len(todo), meta)
    write_outputs(result, mission)
    return result


def _varied(chosen: Sequence[Variant]) -> dict[str, list[Any]]:
    values: dict[str, list[Any]] = {}
    for v in chosen:
        for key, value in v.overrides.items():
            if value not in values.setdefault(key, []):
                values[key].append(value)
    return values


def write_outputs(result: CampaignResult, mission: Any) -> None:
    """Write ``summary.json``, ``campaign.png`` and ``campaign.html`` of a campaign."""
    summary = {**result.meta, "variants": result.rows}
    text = json.dumps(summary, indent=2, allow_nan=False)
    (result.out_dir / SUMMARY_FILE).write_text(text + "\n", encoding="utf-8")
    seeds = result.meta.get("seeds") or [0]
    plot_campaign(
        result.out_dir / PLOT_FILE,
        result.records,
        result.variants,
        terrain=representative_terrain(mission, seeds[0]),
        title=result.meta.get("name", ""),
    )
    write_campaign_html(result, result.out_dir / PAGE_FILE, RUNS_DIR)


@dataclass
class ComparisonResult:
    """Campaigns of several missions over the same seeds, and their paired comparison."""

    out_dir: Path
    names: list[str]
    campaigns: list[CampaignResult]
    rows: list[dict[str, Any]]

    def table(self) -> str:
        """The comparison table as text (first mission = baseline)."""
        return format_comparison(self.rows)


def compare_campaigns(
    missions: Sequence[tuple[str, Any]],
    *,
    runs: int,
    out_dir: str | os.PathLike[str],
    seed: int = 0,
    workers: int | None = None,
    scheduler: str | None = None,
    connect_timeout: float = 10.0,
    backend: Backend | None = None,
    flight: FlightFunction | None = None,
    retry_errors: bool = False,
    progress: TextIO | None = None,
    quiet: bool = False,
    pages: bool = True,
) -> ComparisonResult:
    """Fly the same seeds through each ``(name, mission)`` and compare success rates.

    Each mission's campaign goes to ``out_dir/<name>/``; ``out_dir/compare.json`` holds the
    comparison rows (see :func:`autonomy.campaign.summary.compare_missions`).
    """
    if len(missions) < 2:
        raise UserError("--compare: needs at least two mission files")
    names = [n for n, _ in missions]
    if len(set(names)) != len(names):
        raise UserError("--compare: mission names must differ")
    out = Path(out_dir)
    for name, mission in missions:  # validate everything before the first run
        prepare(mission, runs=runs, seed=seed, flight=flight)
        RunLog(out / name).check_mission(mission_digest(mission))
    own_backend = backend is None
    backend = backend or make_backend(workers, scheduler, connect_timeout)
    try:
        campaigns = [
            run_campaign(mission, runs=runs, out_dir=out / name, seed=seed, backend=backend,
                         flight=flight, retry_errors=retry_errors, progress=progress,
                         quiet=quiet, name=name, pages=pages)
            for name, mission in missions
        ]
    finally:
        if own_backend:
            backend.close()
    rows = compare_missions(names, [c.records for c in campaigns])
    doc = {"seed": seed, "runs": runs, "baseline": names[0], "missions": rows}
    out.mkdir(parents=True, exist_ok=True)
    (out / COMPARE_FILE).write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n")
    return ComparisonResult(out, names, campaigns, rows)
