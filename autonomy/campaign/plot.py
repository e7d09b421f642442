"""``campaign.png``: outcome bars per variant, time-to-land distributions, touchdown points.

Drawn with matplotlib's Agg backend (no display needed). The touchdown panel shows every
run's touchdown over one representative terrain (the world of the campaign's first seed)
when the terrain can be built, else on plain axes.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np

from autonomy.campaign.spec import Variant
from autonomy.campaign.summary import OUTCOME_TITLES, OUTCOMES, outcome_class
from autonomy.report.plot import quiet_missing_glyphs

OUTCOME_COLOURS = {
    "landed": "#2ca02c",
    "landed_unsafe": "#ff7f0e",
    "crashed": "#d62728",
    "no_site": "#9467bd",
    "failsafe": "#e377c2",
    "aborted": "#8c564b",
    "error": "#7f7f7f",
}


def representative_terrain(mission: Any, seed: int) -> Any | None:
    """The terrain world a flight of ``mission`` with run seed ``seed`` flies over (a
    ``sitl.terrain.Terrain``, built as the runner builds it), or None when it cannot be
    built."""
    if getattr(mission, "world", None) is None:
        return None
    try:
        from autonomy.runner.world import FlightSeeds, build_terrain

        return build_terrain(mission, FlightSeeds.derive(seed).terrain)
    except Exception:  # a plot must not fail the campaign
        return None


def _zoom_to_touchdowns(ax: Any, records: Sequence[dict[str, Any]], terrain: Any) -> None:
    """Frame home and every touchdown with a 20 m margin, within the terrain if known."""
    points = np.array([r["touchdown"] for r in records if r.get("touchdown")] + [[0.0, 0.0]],
                      dtype=float)
    lo, hi = points.min(axis=0) - 20.0, points.max(axis=0) + 20.0
    if terrain is not None:
        xmin, xmax, ymin, ymax = terrain.extent
        lo = np.maximum(lo, (xmin, ymin))
        hi = np.minimum(hi, (xmax, ymax))
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")


@quiet_missing_glyphs()
def plot_campaign(
    path: str | os.PathLike[str],
    records: Sequence[dict[str, Any]],
    variants: Sequence[Variant],
    terrain: Any | None = None,
    title: str = "",
) -> None:
    """Write the three-panel campaign figure to ``path`` (PNG)."""
    # imported here: a campaign that draws no figure does not pay for pyplot
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, (ax_out, ax_ttl, ax_map) = plt.subplots(
        1, 3, figsize=(18, max(5.0, 0.45 * len(variants) + 3)), layout="constrained"
    )
    labels = [v.label for v in variants]
    by_variant = {v.key: [r for r in records if r["variant_key"] == v.key] for v in variants}
    rows = np.arange(len(variants))

    left = np.zeros(len(variants))
    for outcome in OUTCOMES:
        counts = np.array(
            [sum(outcome_class(r) == outcome for r in by_variant[v.key]) for v in variants]
        )
        if counts.any():
            ax_out.barh(rows, counts, left=left, color=OUTCOME_COLOURS[outcome],
                        label=OUTCOME_TITLES[outcome])
        left += counts
    ax_out.set_yticks(rows, labels)
    ax_out.invert_yaxis()
    ax_out.set_xlabel("runs")
    ax_out.set_title("outcomes per variant")
    ax_out.legend(loc="lower right", fontsize="small")

    times = [
        [r["time_to_land"] for r in by_variant[v.key]
         if r.get("time_to_land") is not None
         and outcome_class(r) in ("landed", "landed_unsafe")]
        for v in variants
    ]
    if any(times):
        ax_ttl.boxplot([t if t else [np.nan] for t in times], positions=rows,
                       orientation="horizontal", widths=0.6, showfliers=False)
        for row, t in zip(rows, times, strict=True):
            jitter = np.linspace(-0.2, 0.2, len(t)) if len(t) > 1 else np.zeros(len(t))
            ax_ttl.scatter(t, row + jitter, s=8, alpha=0.5, color="#1f77b4")
    else:
        ax_ttl.text(0.5, 0.5, "no landings", ha="center", va="center",
                    transform=ax_ttl.transAxes)
    ax_ttl.set_yticks(rows, labels)
    ax_ttl.set_ylim(len(variants) - 0.5, -0.5)
    ax_ttl.set_xlabel("time to land (sim s)")
    ax_ttl.set_title("time to land (landed runs)")

    if terrain is not None:
        xmin, xmax, ymin, ymax = terrain.extent
        half = terrain.cell_size / 2
        image = ax_map.imshow(
            terrain.grid, origin="lower", cmap="gist_earth",
            extent=(xmin - half, xmax + half, ymin - half, ymax + half),
        )
        fig.colorbar(image, ax=ax_map, shrink=0.8, label="terrain height (m)")
        ax_map.set_title("touchdowns over the terrain of run 0")
    else:
        ax_map.set_title("touchdowns")
        ax_map.set_aspect("equal")
        ax_map.grid(True, alpha=0.3)
    for outcome in OUTCOMES:
        points = np.array(
            [r["touchdown"] for r in records
             if outcome_class(r) == outcome and r.get("touchdown")], dtype=float
        ).reshape(-1, 2)
        if len(points):
            ax_map.scatter(points[:, 0], points[:, 1], s=16, color=OUTCOME_COLOURS[outcome],
                           edgecolors="black", linewidths=0.3, label=OUTCOME_TITLES[outcome])
    ax_map.scatter([0.0], [0.0], marker="^", s=60, color="white", edgecolors="black",
                   label="home", zorder=3)
    _zoom_to_touchdowns(ax_map, records, terrain)
    ax_map.set_xlabel("east (m)")
    ax_map.set_ylabel("north (m)")
    if ax_map.get_legend_handles_labels()[0]:
        ax_map.legend(loc="upper right", fontsize="small")
    if title:
        fig.suptitle(title)
    fig.savefig(path, dpi=100)
    plt.close(fig)
