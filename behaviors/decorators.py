"""Decorators that read time from the injected clock (never the wall clock)."""

from __future__ import annotations

import py_trees
from py_trees.common import Access, Status

from behaviors import blackboard as keys
from behaviors.ports import Clock


class ClockTimeout(py_trees.decorators.Decorator):
    """Run a child for at most ``duration`` seconds of the injected clock.

    Used instead of py_trees' own timeout decorator, which reads the wall clock: the
    deadline is set when the decorator is entered, from ``clock.now()``.

    * SUCCESS / FAILURE: the child finished with it before the deadline
    * RUNNING: the child is running and the deadline has not passed
    * FAILURE: the deadline passed while the child was running; the child is stopped
      (INVALID), and the reason ("<child>: timed out after <d> s (<child's feedback>)") goes to
      the feedback message and :data:`behaviors.blackboard.FAILURE_REASON`

    Args:
        name: the decorator name
        child: the child behaviour or subtree
        clock: the injected clock
        duration: clock seconds allowed, > 0
    """

    def __init__(
        self, name: str, child: py_trees.behaviour.Behaviour, clock: Clock, duration: float
    ) -> None:
        if not duration > 0:
            raise ValueError(f"duration must be > 0 s, got {duration}")
        super().__init__(name=name, child=child)
        self.clock = clock
        self.duration = float(duration)
        self.deadline = float("inf")
        self.blackboard = self.attach_blackboard_client(self.name)
        self.blackboard.register_key(key=keys.FAILURE_REASON, access=Access.WRITE)

    def initialise(self) -> None:
        """Start the countdown."""
        self.deadline = self.clock.now() + self.duration
        self.feedback_message = ""

    def update(self) -> Status:
        """Fail once the deadline passes with the child still running, else mirror it."""
        child = self.decorated
        if child.status == Status.RUNNING and self.clock.now() >= self.deadline:
            detail = f" ({child.feedback_message})" if child.feedback_message else ""
            reason = f"{child.name}: timed out after {self.duration:g} s{detail}"
            child.stop(Status.INVALID)
            self.feedback_message = reason
            self.blackboard.set(keys.FAILURE_REASON, reason)
            return Status.FAILURE
        if child.status == Status.RUNNING:
            self.feedback_message = f"{self.deadline - self.clock.now():.1f} s left"
        return child.status
