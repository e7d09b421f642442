"""Link health during a flight: loss and regain as events, and the hold-and-wait policy.

Policy (README "Link loss"): once the driver declares the link lost (no autopilot HEARTBEAT
for ``vehicle.link.link_timeout``), the mission holds: the tree is not ticked, so no running
behaviour fails on the commands the loss cancelled, and the autopilot keeps its last target
or flies its own failsafe. If the link comes back within ``vehicle.link.loss_wait`` clock
seconds the mission resumes: the running behaviour is restarted so that it re-issues its
command. If it does not, or if the autopilot changed mode on its own meanwhile (its
failsafe took over), the flight ends with outcome ``link_lost``; nothing is sent over the
dead link to land.
"""

from __future__ import annotations

import enum
from typing import Any

from autonomy.report.events import EventLog


class Link(enum.Enum):
    """What the flight should do this tick."""

    UP = "up"  # heard (or not heard yet): fly on
    HOLDING = "holding"  # lost, still waiting for it
    RESUMED = "resumed"  # back this tick: restart what was running, then fly on
    GAVE_UP = "gave_up"  # lost for too long: end the flight


class LinkWatch:
    """Watches ``vehicle.state.link_lost`` each tick and applies the policy above.

    Args:
        vehicle: the MAVLink vehicle (its ``state``, ``stats`` and ``mode_changes``).
        log: the flight's event log (``link`` events: lost, regained, gave_up, never_heard).
        loss_wait: clock seconds to hold for a lost link before giving up.
        note: prints a console line now (``note(t, text)``), or None.
    """

    def __init__(self, vehicle: Any, log: EventLog, loss_wait: float, note: Any = None) -> None:
        self.vehicle = vehicle
        self.log = log
        self.loss_wait = float(loss_wait)
        self.note = note
        self.lost_since: float | None = None
        self.gave_up: str | None = None  # why the flight ended on the link

    def _say(self, now: float, text: str) -> None:
        if self.note is not None:
            self.note(now, text)

    def update(self, now: float) -> Link:
        """Decide for this tick from the state the last poll built."""
        if self.gave_up is not None:
            return Link.GAVE_UP
        state = self.vehicle.state
        heard = self.vehicle.stats.first_heartbeat is not None
        if not heard:
            return Link.UP  # never heard: the connection wait bounds this, not the policy
        if state.link_lost:
            if self.lost_since is None:
                self.lost_since = now
                self.log.add("link", event="lost", silent_for=state.heartbeat_age,
                             wait=self.loss_wait)
                self._say(now, f"LINK LOST: no heartbeat for {state.heartbeat_age:.1f} s; "
                          f"holding the mission up to {self.loss_wait:g} s (the autopilot "
                          "keeps its target or flies its own failsafe)")
            if now - self.lost_since >= self.loss_wait:
                return self._give_up(now, f"link lost for {now - self.lost_since:.1f} s "
                                     f"(vehicle.link.loss_wait {self.loss_wait:g} s)")
            return Link.HOLDING
        if self.lost_since is None:
            return Link.UP
        lost_for = now - self.lost_since
        since = self.lost_since
        self.lost_since = None
        taken = [c for c in self.vehicle.mode_changes if c.time >= since and not c.requested]
        self.log.add("link", event="regained", lost_for=lost_for, mode=state.mode)
        if taken:
            # The autopilot's own failsafe (or an operator) took the vehicle: leave it so.
            return self._give_up(now, f"link back after {lost_for:.1f} s, but the autopilot "
                                 f"switched to {taken[-1].new} meanwhile: left in its charge")
        self._say(now, f"link back after {lost_for:.1f} s; resuming the mission")
        return Link.RESUMED

    def never_heard(self, now: float, url: str, waited: float) -> None:
        """End the flight: nothing was heard on ``url`` for ``waited`` clock seconds."""
        self.gave_up = (f"no heartbeat on {url} within {waited:g} s (is the autopilot "
                        "running, and is the URL right?)")
        self.log.add("link", event="never_heard", url=url, waited=waited)
        self._say(now, self.gave_up)

    def _give_up(self, now: float, reason: str) -> Link:
        self.gave_up = reason
        self.log.add("link", event="gave_up", reason=reason)
        self._say(now, f"giving up: {reason}; outcome link_lost")
        return Link.GAVE_UP
