"""The blackboard log: the mission's blackboard values as they change, in JSON lines.

Written beside the tick log (:mod:`behaviors.btlog`) as ``blackboard.jsonl``. The first
lines hold every key's value when the log was opened, then one line per key whose value
changed during a tick, stamped with the clock's time (the same time as that tick's
transitions in the ``.btlog``)::

    {"t": 12.3, "key": "/landing/site", "value": {"id": 4, "x": 10.5, ...}}

Values are JSON: records (e.g. an ``lsm.LandingSite``) as objects of their fields, tuples as
lists, NaN and infinities as null. Each tick's lines are flushed when the tick ends.

Python API: :func:`read_blackboard_log` returns the entries as dicts.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Callable, Iterable
from typing import IO, Any

import py_trees


def jsonable(value: Any) -> Any:
    """``value`` as plain JSON data (see the module docstring)."""
    if value is None or isinstance(value, (bool, int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: jsonable(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if hasattr(value, "item"):  # numpy scalars
        return jsonable(value.item())
    return str(value)


class BlackboardLogger:
    """Post-tick handler writing the changes of ``keys`` to a JSON-lines file.

    Args:
        path: the file (created or replaced).
        keys: absolute blackboard keys to follow.
        now: the clock (seconds).
    """

    def __init__(self, path: str | os.PathLike[str], keys: Iterable[str],
                 now: Callable[[], float]) -> None:
        self.keys = tuple(keys)
        self.now = now
        self.file: IO[str] | None = open(path, "w", encoding="utf-8")  # noqa: SIM115
        self.last = self._values()
        t = float(now())
        for key, value in zip(self.keys, self.last, strict=True):
            self._write(t, key, value)
        self.file.flush()

    def _values(self) -> list[Any]:
        storage = py_trees.blackboard.Blackboard.storage
        return [storage.get(key) for key in self.keys]

    def _write(self, t: float, key: str, value: Any) -> None:
        assert self.file is not None
        line = json.dumps({"t": round(t, 6), "key": key, "value": jsonable(value)},
                          allow_nan=False)
        self.file.write(line + "\n")

    def attach(self, tree: py_trees.trees.BehaviourTree) -> BlackboardLogger:
        tree.add_post_tick_handler(self)
        return self

    def __call__(self, tree: py_trees.trees.BehaviourTree) -> None:
        if self.file is None:
            return
        values = self._values()
        if values == self.last:
            return
        t = float(self.now())
        for key, old, new in zip(self.keys, self.last, values, strict=True):
            if new is not old and new != old:
                self._write(t, key, new)
        self.last = values
        self.file.flush()

    def close(self) -> None:
        if self.file is not None:
            self.file.close()
            self.file = None


def read_blackboard_log(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The entries of a ``blackboard.jsonl`` in order; a last line cut short by an
    interrupted flight is left out."""
    entries = []
    with open(path, encoding="utf-8") as handle:
        for line in handle:
            try:
                entries.append(json.loads(line))
            except json.JSONDecodeError:
                break
    return entries
