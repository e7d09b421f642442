"""Stand-in flights for campaign tests that exercise the machinery, not the autopilot.

Imported as the top-level module ``fake_flights`` (conftest puts this directory on sys.path,
which spawned workers inherit) so that worker processes can unpickle these functions.
"""

from __future__ import annotations

import os
import signal
from typing import Any

import numpy as np
from pydantic import BaseModel, ConfigDict


class FakeMission(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    success_rate: float = 0.7
    raise_when_above: float | None = None  # the flight raises when success_rate exceeds it
    die_on_seed: int | None = None  # the worker process exits abruptly on this seed
    kill_on_seed: int | None = None  # the worker process is killed (SIGKILL) on this seed


def apply(mission: FakeMission, overrides: dict[str, Any]) -> FakeMission:
    unknown = set(overrides) - set(FakeMission.model_fields)
    if unknown:
        from autonomy.errors import UserError

        raise UserError(f"override {sorted(unknown)[0]}: unknown setting")
    return FakeMission.model_validate({**mission.model_dump(), **overrides})


def fly(mission: FakeMission, seed: int, out_dir: Any = None) -> dict[str, Any]:
    if mission.die_on_seed == seed:
        os._exit(3)
    if mission.kill_on_seed == seed:  # as the kernel's OOM killer does
        os.kill(os.getpid(), signal.SIGKILL)
    if mission.raise_when_above is not None and mission.success_rate > mission.raise_when_above:
        raise RuntimeError("deliberate failure of this variant")
    rng = np.random.default_rng(seed)
    landed = bool(rng.random() < mission.success_rate)
    touchdown = rng.normal(0.0, 20.0, size=2)
    outcome = "landed" if landed else str(rng.choice(["crashed", "no_site"]))
    return {
        "outcome": outcome,
        "outcome_hint": "no_site" if outcome == "no_site" else None,
        "touchdown_safe": landed,
        "time_to_land": float(rng.uniform(60, 200)) if landed else None,
        "distance": float(rng.uniform(100, 500)),
        "energy": float(rng.uniform(1e4, 5e4)),
        "sites_received": int(rng.integers(0, 50)),
        "sites_verified": int(landed),
        "sites_banned": 0,
        "verification_attempts": 1,
        "search_patterns": 0,
        "mission_time": 250.0,
        "touchdown": touchdown if landed else None,
    }
