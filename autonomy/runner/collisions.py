"""Counting a lockstep flight's collisions against the simulator's ground truth
(:class:`sitl.terrain.contact.ContactJudge`): one per contact with a new obstacle, an event
for each, the first kept for summary.json."""

from __future__ import annotations

from typing import Any

from autonomy.report.events import EventLog


class CollisionWatch:
    """Judges the vehicle's true position every tick.

    Args:
        judge: a :class:`sitl.terrain.contact.ContactJudge` of the flight's world.
        log: the flight's event log (``flight`` / ``collision`` events).
    """

    def __init__(self, judge: Any, log: EventLog) -> None:
        self.judge = judge
        self.log = log
        self.count = 0
        self.first: dict[str, Any] | None = None
        self._touching: tuple[str, int | None] | None = None

    def update(self, now: float, position) -> None:
        """The vehicle (its skids) at ``position`` (ENU m) at clock time ``now``: a contact
        with another obstacle than the one touched on the tick before is a new collision."""
        contact = self.judge.contact(position, now)
        if contact is None:
            self._touching = None
            return
        touching = (contact.obstacle, contact.index)
        if touching != self._touching:
            self.count += 1
            record = contact.as_dict()
            if self.first is None:
                self.first = record
            self.log.add("flight", event="collision", **record)
        self._touching = touching
