"""Monte-Carlo campaigns: many seeded lockstep flights of a mission, locally or on Dask.

See :func:`run_campaign` and :func:`compare_campaigns`; the ``--vary`` grammar is in
:mod:`autonomy.campaign.spec`, the intervals in :mod:`autonomy.campaign.stats`.

Names are imported on first use, so that worker processes, which only need
:mod:`autonomy.campaign.worker`, do not pay for scipy and matplotlib.
"""

from __future__ import annotations

import importlib
from typing import Any

_EXPORTS = {
    "DaskCluster": "backends",
    "LocalPool": "backends",
    "make_backend": "backends",
    "CampaignResult": "engine",
    "ComparisonResult": "engine",
    "compare_campaigns": "engine",
    "prepare": "engine",
    "run_campaign": "engine",
    "RunTask": "plan",
    "run_seed": "plan",
    "Vary": "spec",
    "Variant": "spec",
    "parse_values": "spec",
    "parse_vary": "spec",
    "variants": "spec",
    "newcombe_interval": "stats",
    "newcombe_paired_interval": "stats",
    "wilson_interval": "stats",
    "compare_missions": "summary",
    "format_table": "summary",
    "summarise": "summary",
    "NONDETERMINISTIC_FIELDS": "worker",
    "fly_run": "worker",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
