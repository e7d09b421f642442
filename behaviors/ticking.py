"""py_trees' tick and stop, step for step, without the debug messages built on every call.

py_trees formats a debug line (the class name and, on stop, both statuses as text) on every
tick and stop of every node and checks each returned status against ``list(Status)``; the
lines are dropped unless py_trees' logging is at debug level, but building them was a fifth
of a lockstep tick of the landing tree. The classes here are py_trees' own (subclasses,
``isinstance`` holds) with ``tick`` and ``stop`` copied from py_trees 2.x minus those
messages, so a tree built from them changes state exactly as py_trees' does
(tests/behaviors/test_ticking.py ticks both side by side). Errors py_trees logs (an invalid
status) are still logged.

Each class also has ``run``, the same tick as a plain call: a tree nobody visits (no
py_trees visitor, the flight's case; see :class:`behaviors.tree.MissionTree`) needs none of
the nodes a tick yields, and a generator per node per tick was a third of the tick. ``run``
makes the same calls in the same order as draining ``tick`` (tests/behaviors/test_ticking.py).
:func:`run_observed` is ``run`` for a tree that py_trees visitors watch (the flight's
``.btlog``): it shows an observer every node where draining ``tick`` would yield it, in the
same order and state.
``stop`` no longer makes the fresh, never-started ``tick`` generator py_trees stores in
``iterator`` on every stop (nothing reads it), and ``run`` and ``stop`` skip the calls of
``initialise`` and ``terminate`` a class does not override (py_trees' own do nothing).
"""

from __future__ import annotations

import itertools
from collections.abc import Callable, Iterator

import py_trees
from py_trees.behaviour import Behaviour
from py_trees.common import Status

_STATUSES = tuple(Status)
_RUNNING = Status.RUNNING
_SUCCESS = Status.SUCCESS
_FAILURE = Status.FAILURE
_INVALID = Status.INVALID

# Shown every node where its tick would yield it, while run_observed runs (else None).
_observer: Callable[[Behaviour], None] | None = None


def _conclude(node: Behaviour, new_status: Status) -> None:
    """The end of py_trees' tick: an invalid status is logged and made INVALID; a finished
    node is stopped; the status is set."""
    if new_status not in _STATUSES:
        node.logger.error(f"A behaviour returned an invalid status, setting to INVALID "
                          f"[{new_status}][{node.name}]")
        new_status = _INVALID
    if new_status != _RUNNING:
        node.stop(new_status)
    node.status = new_status


class Direct:
    """What the classes here share: ``run``, their tick without yielding. A subclass that
    writes its own ``tick`` (and no ``run``) is run through that ``tick``.

    ``_initialises`` and ``_terminates`` say whether the class has an ``initialise`` or a
    ``terminate`` of its own; py_trees' are empty, and calling them is skipped.
    ``_bare_stop``: the class's ``stop`` only sets the status (a leaf with
    :class:`QuietBehaviour`'s ``stop`` and no ``terminate``), so a parent sets it instead of
    calling ``stop`` (:func:`_stop`)."""

    _initialises = True
    _terminates = True
    _bare_stop = False

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        if "tick" in cls.__dict__ and "run" not in cls.__dict__:
            cls.run = _drain
        cls._initialises = cls.initialise is not Behaviour.initialise
        cls._terminates = cls.terminate is not Behaviour.terminate
        cls._bare_stop = not cls._terminates and getattr(cls.stop, "sets_status_only", False)

    def run(self) -> None:  # pragma: no cover - every class here defines its own
        _drain(self)

    @property
    def feedback_message(self) -> str:
        """py_trees' feedback message. One set by :meth:`feedback_later` is formatted when
        it is first read."""
        text = self._feedback
        if text.__class__ is tuple:
            text = self._feedback = text[0].format(*text[1:])
        return text

    @feedback_message.setter
    def feedback_message(self, text: str) -> None:
        self._feedback = text

    def feedback_later(self, template: str, *values: object) -> None:
        """Make the feedback message ``template.format(*values)``, formatted only if it is
        read: a running node says where it is on every tick, and few of those messages are
        ever read (the event log reads it when a status changes)."""
        self._feedback = (template, *values)


def _drain(node: Behaviour) -> None:
    """Tick ``node`` through its generator (a node from elsewhere, e.g. py_trees' Parallel)."""
    if _observer is None:
        for _ in node.tick():
            pass
    else:
        for yielded in node.tick():
            _observer(yielded)


def run(node: Behaviour) -> None:
    """Tick ``node`` once, as draining its ``tick`` does."""
    if isinstance(node, Direct):
        node.run()
    else:
        _drain(node)


def run_observed(node: Behaviour, observer: Callable[[Behaviour], None]) -> None:
    """Tick ``node`` once as :func:`run` does, calling ``observer(n)`` for every node ``n``
    that draining ``node.tick()`` would yield, at the moment it would yield it (what a
    py_trees visitor sees)."""
    global _observer
    _observer = observer
    try:
        run(node)
    finally:
        _observer = None


class QuietBehaviour(Direct, Behaviour):
    """A leaf: :class:`py_trees.behaviour.Behaviour`'s ``tick`` and ``stop``."""

    def tick(self) -> Iterator[Behaviour]:
        if self.status != _RUNNING:
            self.initialise()
        _conclude(self, self.update())
        yield self

    def run(self) -> None:
        if self.status is not _RUNNING and self._initialises:
            self.initialise()
        status = self.update()
        if status is _RUNNING:
            self.status = status
        elif status is _SUCCESS or status is _FAILURE:
            if not self._bare_stop:
                self.stop(status)
            self.status = status
        else:
            _conclude(self, status)
        if _observer is not None:
            _observer(self)

    def stop(self, new_status: Status) -> None:
        if self._terminates:
            self.terminate(new_status)
        self.status = new_status

    stop.sets_status_only = True  # when terminate is py_trees' (see Direct._bare_stop)


class QuietDecorator(Direct, py_trees.decorators.Decorator):
    """A decorator: :class:`py_trees.decorators.Decorator`'s ``tick`` and ``stop``."""

    def tick(self) -> Iterator[Behaviour]:
        if self.status != _RUNNING:
            self.initialise()
        yield from self.decorated.tick()
        _conclude(self, self.update())
        yield self

    def run(self) -> None:
        if self.status is not _RUNNING and self._initialises:
            self.initialise()
        decorated = self.decorated
        if isinstance(decorated, Direct):
            decorated.run()
        else:
            _drain(decorated)
        _conclude(self, self.update())
        if _observer is not None:
            _observer(self)

    def stop(self, new_status: Status) -> None:
        if self._terminates:
            self.terminate(new_status)
        if new_status == _INVALID:
            _stop(self.decorated, new_status)
        if self.decorated.status == _RUNNING:
            _stop(self.decorated, _INVALID)
        self.status = new_status


class Retry(QuietDecorator, py_trees.decorators.Retry):
    """:class:`py_trees.decorators.Retry`."""


class Inverter(QuietDecorator, py_trees.decorators.Inverter):
    """:class:`py_trees.decorators.Inverter`."""


def _stop(node: Behaviour, new_status: Status) -> None:
    """``node.stop(new_status)``; for a node whose stop only sets the status, that alone."""
    if getattr(node, "_bare_stop", False):
        node.status = new_status
    else:
        node.stop(new_status)


def _invalidate_from(children: list[Behaviour], start: int) -> None:
    """Stop (INVALID) every child from index ``start`` on that is not INVALID already."""
    for other in itertools.islice(children, start, None):
        if other.status != _INVALID:
            _stop(other, _INVALID)


def _invalidate_after(children: list[Behaviour], current: Behaviour) -> None:
    """A selector interrupted by ``current``: stop everything at a lower priority (after it),
    as py_trees' Selector does."""
    passed = False
    for other in children:
        if passed and other.status != _INVALID:
            _stop(other, _INVALID)
        passed = True if other == current else passed


def _resume_index(selector, children: list[Behaviour]) -> int:
    """Where a selector's tick starts: with memory, at its current child (those before it
    invalidated); else at the first."""
    if not selector.memory:
        return 0
    assert selector.current_child is not None
    index = children.index(selector.current_child)
    for child in itertools.islice(children, None, index):
        if child.status != _INVALID:
            _stop(child, _INVALID)
    return index


def _stop_composite(node: py_trees.composites.Composite, new_status: Status = _INVALID) -> None:
    """py_trees' ``Composite.stop`` (the ``stop`` of :class:`Selector` and :class:`Sequence`)."""
    if new_status == _INVALID:
        node.current_child = None
        for child in node.children:
            if child.status != _INVALID:
                if getattr(child, "_bare_stop", False):
                    child.status = new_status
                else:
                    child.stop(new_status)
    if node._terminates:
        node.terminate(new_status)
    node.status = new_status


class Selector(Direct, py_trees.composites.Selector):
    """:class:`py_trees.composites.Selector`."""

    def tick(self) -> Iterator[Behaviour]:
        children = self.children
        if self.status != _RUNNING:
            self.current_child = children[0] if children else None
            self.initialise()
        if not children:
            self.current_child = None
            self.stop(_FAILURE)
            yield self
            return
        index = _resume_index(self, children)
        previous = self.current_child
        for child in itertools.islice(children, index, None):
            for node in child.tick():
                yield node
                if node is child and (node.status == _RUNNING or node.status == _SUCCESS):
                    self.current_child = child
                    if previous is None or previous != self.current_child:
                        _invalidate_after(children, self.current_child)
                    if node.status == _SUCCESS:
                        self.stop(node.status)
                    else:
                        self.status = node.status
                    yield self
                    return
        self.stop(_FAILURE)
        self.current_child = children[-1] if children else None
        yield self

    def run(self) -> None:
        children = self.children
        if self.status is not _RUNNING:
            self.current_child = children[0] if children else None
            if self._initialises:
                self.initialise()
        if not children:
            self.current_child = None
            self.stop(_FAILURE)
            if _observer is not None:
                _observer(self)
            return
        index = _resume_index(self, children)
        previous = self.current_child
        for child in itertools.islice(children, index, None) if index else children:
            if isinstance(child, Direct):
                child.run()
            else:
                _drain(child)
            if child.status is _RUNNING or child.status is _SUCCESS:
                self.current_child = child
                if previous is None or previous != self.current_child:
                    _invalidate_after(children, self.current_child)
                if child.status == _SUCCESS:
                    self.stop(child.status)
                else:
                    self.status = child.status
                if _observer is not None:
                    _observer(self)
                return
        self.stop(_FAILURE)
        self.current_child = children[-1] if children else None
        if _observer is not None:
            _observer(self)

    stop = _stop_composite


class Sequence(Direct, py_trees.composites.Sequence):
    """:class:`py_trees.composites.Sequence`."""

    def tick(self) -> Iterator[Behaviour]:
        children = self.children
        index = 0
        if self.status != _RUNNING:
            self.current_child = children[0] if children else None
            for child in children:
                if child.status != _INVALID:
                    child.stop(_INVALID)
            self.initialise()
        elif self.memory and self.current_child is not None:
            index = children.index(self.current_child)
        else:
            self.current_child = children[0] if children else None
        if not children:
            self.current_child = None
            self.stop(_SUCCESS)
            yield self
            return
        for child in itertools.islice(children, index, None):
            for node in child.tick():
                yield node
                if node is child and node.status != _SUCCESS:
                    if not self.memory:
                        _invalidate_from(children, index + 1)  # dangling runners after it
                    if node.status != _RUNNING:
                        self.stop(node.status)
                    else:
                        self.status = node.status
                    yield self
                    return
            if index + 1 < len(children):
                self.current_child = children[index + 1]
                index += 1
        self.stop(_SUCCESS)
        yield self

    def run(self) -> None:
        children = self.children
        index = 0
        if self.status is not _RUNNING:
            self.current_child = children[0] if children else None
            for child in children:
                if child.status is not _INVALID:
                    _stop(child, _INVALID)
            if self._initialises:
                self.initialise()
        elif self.memory and self.current_child is not None:
            index = children.index(self.current_child)
        else:
            self.current_child = children[0] if children else None
        if not children:
            self.current_child = None
            self.stop(_SUCCESS)
            if _observer is not None:
                _observer(self)
            return
        for child in itertools.islice(children, index, None) if index else children:
            if isinstance(child, Direct):
                child.run()
            else:
                _drain(child)
            if child.status is not _SUCCESS:
                if not self.memory:
                    _invalidate_from(children, index + 1)  # dangling runners after it
                if child.status != _RUNNING:
                    self.stop(child.status)
                else:
                    self.status = child.status
                if _observer is not None:
                    _observer(self)
                return
            if index + 1 < len(children):
                self.current_child = children[index + 1]
                index += 1
        self.stop(_SUCCESS)
        if _observer is not None:
            _observer(self)

    stop = _stop_composite


__all__ = ["Direct", "Inverter", "QuietBehaviour", "QuietDecorator", "Retry", "Selector",
           "Sequence", "run", "run_observed"]
