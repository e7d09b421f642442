"""The interface between the runner and whatever produces landing-site observations."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

from behaviors.ports import VehicleState
from lsm.records import SiteObservation


class SiteSource(Protocol):
    """Produces site observations from the vehicle's pose (as reported over MAVLink).

    ``update`` is called by the runner at the perception rate with the latest vehicle state
    and the clock time; it returns the observations to submit to the LSM. It never raises
    on bad sensor data: it drops what is bad and records why in its events.
    """

    def update(self, state: VehicleState, now: float) -> Sequence[SiteObservation]: ...

    def drain_events(self) -> list[dict[str, Any]]:
        """Events since the last call (e.g. a depth-source switch), each a JSON-able dict
        with at least ``"event"``; the runner stamps them with the time and logs them."""
        ...
