"""The flight's event log (events.jsonl) and the tree-status recorder that feeds it.

Every event is a JSON object with ``t`` (clock seconds), ``kind`` (``tree``, ``phase``,
``lsm``, ``perception``, ``flight``, ``link``) and kind-specific fields. Events carry nothing that
differs between two runs with the same seed (no wall time, no object ids), so a lockstep
flight's events.jsonl is reproducible byte for byte.
"""

from __future__ import annotations

import json
import math
import operator
import threading
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import numpy as np
import py_trees

from autonomy.vehicle.frames import Degrees

# json.dumps(event, separators=(",", ":")) without building an encoder per event.
_ENCODE = json.JSONEncoder(separators=(",", ":")).encode


def _clean(value: Any) -> Any:
    """A JSON-able copy: numpy scalars to Python, floats rounded to 0.1 mm / 0.1 ms, and
    latitudes and longitudes (:class:`~autonomy.vehicle.frames.Degrees`) to 1e-7 degrees."""
    kind = type(value)  # the common plain types first, each as the chain below treats it
    if kind is float:
        return round(value, 4) if math.isfinite(value) else None
    if kind is Degrees:
        return round(float(value), 7) if math.isfinite(value) else None
    if kind is str or kind is int or kind is bool or value is None:
        return value
    if kind is dict:
        return _clean_dict(value)
    if kind is tuple or kind is list:
        return [_clean(v) for v in value]
    if kind is np.ndarray and value.dtype.kind in "fiub":
        # tolist() gives the Python numbers the chain below would make of each element,
        # without a numpy scalar per element (a report page holds thousands).
        return _clean(value.tolist())
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return round(value, 4) if math.isfinite(value) else None
    if isinstance(value, dict):
        return _clean_dict(value)
    if isinstance(value, (list, tuple, np.ndarray)):
        return [_clean(v) for v in value]
    if value is None or isinstance(value, str):
        return value
    return str(value)


def _clean_dict(value: dict) -> dict[str, Any]:
    """``{str(k): _clean(v)}``, the plain values of an event cleaned in line (an event is a
    dict of a few floats, strings and ints)."""
    out = {}
    for key, item in value.items():
        kind = type(item)
        if kind is float:
            item = round(item, 4) if math.isfinite(item) else None
        elif not (kind is str or kind is int or kind is bool or item is None):
            item = _clean(item)
        out[key if type(key) is str else str(key)] = item
    return out


class EventLog:
    """Flight events in time order, kept in memory and optionally streamed to a file.

    Args:
        now: the clock's ``now`` that stamps each event.
        path: events.jsonl to write (one JSON object per line), or None.
    """

    def __init__(self, now: Callable[[], float], path: Path | None = None) -> None:
        self._now = now
        self.events: list[dict[str, Any]] = []
        self._path = path
        self._file: IO[str] | None = None  # opened at the first event: no empty files
        self._unflushed = False
        self._lock = threading.Lock()  # live flights log from the LSM worker thread too

    def add(self, kind: str, **fields: Any) -> dict[str, Any]:
        """Record one event of ``kind`` now; returns it. It reaches the file at the next
        :meth:`flush` (the runner flushes after every tick) or :meth:`close`."""
        event = _clean_dict({"t": self._now(), "kind": kind, **fields})
        with self._lock:
            self.events.append(event)
            if self._path is not None:
                if self._file is None:
                    self._file = self._path.open("w", encoding="utf-8")
                self._file.write(_ENCODE(event) + "\n")
                self._unflushed = True
        return event

    def flush(self) -> None:
        """Write the events added since the last flush to the file. Once per tick rather
        than once per event (a Mars flight logs some 7000, mostly the LSM's, in bursts): a
        live flight is still followed with tail -f, and a killed run keeps every tick's
        events but those of the tick it was killed in."""
        if self._unflushed:
            with self._lock:
                if self._file is not None:
                    self._file.flush()
                self._unflushed = False

    def close(self) -> None:
        with self._lock:
            self._unflushed = False
            if self._file is not None:
                self._file.close()
                self._file = None
            self._path = None


def read_events(path: str | Path) -> list[dict[str, Any]]:
    """The events of an events.jsonl file."""
    with Path(path).open(encoding="utf-8") as f:
        return [json.loads(line) for line in f if line.strip()]


_STATUS = operator.attrgetter("status")


class TreeStatusRecorder:
    """Post-tick handler logging every status change of every behaviour in a tree.

    Each change becomes a ``tree`` event with the behaviour's name, its path from the root
    (names joined by ``/``), the old and new status and its feedback message. Statuses are
    compared over the whole tree after each tick, so behaviours invalidated by a parent
    (a preempted branch) are recorded too.
    """

    def __init__(self, log: EventLog) -> None:
        self._log = log
        self._statuses: list[py_trees.common.Status] = []
        self._paths: dict[int, str] = {}
        self._root: py_trees.behaviour.Behaviour | None = None
        self._nodes: list[py_trees.behaviour.Behaviour] = []

    def _path(self, node: py_trees.behaviour.Behaviour) -> str:
        key = id(node)
        path = self._paths.get(key)
        if path is None:
            names = []
            walk: py_trees.behaviour.Behaviour | None = node
            while walk is not None:
                names.append(walk.name)
                walk = walk.parent
            path = self._paths[key] = "/".join(reversed(names))
        return path

    def __call__(self, tree: py_trees.trees.BehaviourTree) -> None:
        if tree.root is not self._root:  # the tree's shape is fixed: flatten it once
            self._root = tree.root
            self._nodes = list(tree.root.iterate())
            self._statuses = [py_trees.common.Status.INVALID] * len(self._nodes)
        # One pass in C over the statuses; Python only for the few that changed.
        now = list(map(_STATUS, self._nodes))
        if now == self._statuses:
            return
        for i, (old, new) in enumerate(zip(self._statuses, now, strict=True)):
            if new is not old:
                node = self._nodes[i]
                self._log.add(
                    "tree", behaviour=node.name, path=self._path(node), old=old.value,
                    new=new.value, feedback=node.feedback_message,
                )
        self._statuses = now
