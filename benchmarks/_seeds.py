"""The flights a benchmark flies: seeds given by hand, or those of a campaign's first runs.

Seeds 0 and 1 (the default) are two cheap Mars flights; a campaign flies run ``i`` with
``run_seed(0, i)``, and those flights spend longer low over the terrain. ``--campaign-runs
N`` measures the flights that ``lander campaign MISSION --runs N`` flies, so a per-core
figure can be set beside a campaign's throughput.
"""

from __future__ import annotations

import argparse


def add_seed_arguments(parser: argparse.ArgumentParser) -> None:
    """``--seeds S [S ...]`` (default 0 1) or ``--campaign-runs N``, not both."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--seeds", type=int, nargs="+", default=[0, 1],
                       help="mission seeds to fly (default 0 1)")
    group.add_argument("--campaign-runs", type=_positive, metavar="N", default=None,
                       help="fly the seeds of runs 0..N-1 of `lander campaign` (campaign "
                       "seed 0), the flights a campaign's throughput comes from")


def chosen_seeds(args: argparse.Namespace) -> list[int]:
    """The seeds ``args`` ask for (``--campaign-runs`` resolved to the campaign's seeds)."""
    if args.campaign_runs is None:
        return list(args.seeds)
    from autonomy.campaign.plan import run_seed

    return [run_seed(0, index) for index in range(args.campaign_runs)]


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value
