"""What a campaign flies: one task per (variant, seed), with seeds derived from one seed.

Run ``i`` of every variant flies with the same seed, ``SeedSequence(seed).spawn(...)[i]``
reduced to a 32-bit integer, so variants (and missions under ``--compare``) are compared on
the same terrains, noise and wind (common random numbers), and growing ``--runs`` keeps the
seeds of the runs already flown.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from autonomy import __version__
from autonomy.campaign.spec import Variant

#: ``fly(mission, seed=..., out_dir=None)`` returning an object with a ``summary`` dict.
FlightFunction = Callable[..., Any]
#: ``apply_overrides(mission, {"dotted.key": value})`` returning a new mission.
OverrideFunction = Callable[[Any, dict[str, Any]], Any]


def run_seed(seed: int, index: int) -> int:
    """Seed of run ``index`` of a campaign seeded with ``seed``: the ``index``-th child of
    ``numpy.random.SeedSequence(seed)`` (as ``spawn`` makes it), as an int in [0, 2**32)."""
    child = np.random.SeedSequence(seed, spawn_key=(index,))
    return int(child.generate_state(1, dtype=np.uint32)[0])


def mission_digest(mission: Any) -> str:
    """Short fingerprint of a mission as its user wrote it (``Mission.source_data()``: the
    file's settings, not its comments), with the package version.

    Defaults are left out on purpose, so that a schema growing new defaulted settings does
    not orphan the runs already recorded for an unchanged mission file.
    """
    source = getattr(mission, "source_data", None)
    if callable(source):
        text = json.dumps(source(), sort_keys=True, default=str)
    else:
        dump = getattr(mission, "model_dump_json", None)
        text = dump() if callable(dump) else repr(mission)
    return hashlib.sha256(f"{__version__}\n{text}".encode()).hexdigest()[:16]


@dataclass(frozen=True)
class RunTask:
    """One flight of a campaign, picklable so that any worker process can fly it.

    ``mission`` already has the variant's overrides applied; ``flight`` is a top-level
    function (pickled by reference) such as :func:`autonomy.runner.fly`, called with
    ``out_dir``.
    """

    run_id: str
    mission_id: str
    variant: int
    variant_key: str
    variant_label: str
    values: dict[str, Any]
    seed_index: int
    seed: int
    mission: Any
    flight: FlightFunction
    out_dir: str | None = None  # the run's report folder (its flight page), or None

    @property
    def identity(self) -> tuple[str, str, int]:
        """What a recorded run must match to count as this task: mission, variant, seed."""
        return (self.mission_id, self.variant_key, self.seed)


def plan(
    mission: Any,
    variants: Sequence[Variant],
    runs: int,
    seed: int,
    flight: FlightFunction,
    apply_overrides: OverrideFunction | None,
) -> list[RunTask]:
    """All tasks of a campaign, variant-major. Applying every variant's overrides here
    validates them before any run starts (bad keys or values raise there)."""
    mission_id = mission_digest(mission)
    seeds = [run_seed(seed, i) for i in range(runs)]
    tasks = []
    for variant in variants:
        if variant.overrides:
            if apply_overrides is None:
                raise ValueError("varied keys need an apply_overrides function")
            varied = apply_overrides(mission, dict(variant.overrides))
        else:
            varied = mission
        for i, run_seed_ in enumerate(seeds):
            tasks.append(
                RunTask(
                    run_id=f"v{variant.index:03d}-r{i:05d}",
                    mission_id=mission_id,
                    variant=variant.index,
                    variant_key=variant.key,
                    variant_label=variant.label,
                    values=dict(variant.overrides),
                    seed_index=i,
                    seed=run_seed_,
                    mission=varied,
                    flight=flight,
                )
            )
    return tasks
