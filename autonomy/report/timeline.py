"""The tree's timeline for report.html: which node ran when, with which status.

Built from the flight's ``tree.btlog`` (BehaviorTree.CPP FileLogger2, see
:mod:`autonomy.report.btlog`) when there is one, else from the ``tree`` events of
events.jsonl. Either way the result is a list of lanes (one per node, parents before their
children) and segments ``[lane, start, end, status]``: the node held ``status`` from
``start`` to ``end`` (clock seconds); idle/invalid time is no segment.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from autonomy.report.btlog import BtLog

# Status codes of the segments, as BehaviorTree.CPP numbers them (0 = idle: no segment).
CODES = {"IDLE": 0, "INVALID": 0, "RUNNING": 1, "SUCCESS": 2, "FAILURE": 3, "SKIPPED": 4}


@dataclass
class Timeline:
    """Lanes ``{"name", "path", "depth"}`` and segments ``[lane, start, end, code]``."""

    source: str
    lanes: list[dict[str, Any]]
    segments: list[list[float]]
    truncated: bool = False

    def as_dict(self) -> dict[str, Any]:
        return {"source": self.source, "lanes": self.lanes, "segments": self.segments,
                "truncated": self.truncated}


def segments(lane: np.ndarray, time: np.ndarray, code: np.ndarray, end: float) -> list:
    """Segments from transitions (any order): each transition of a lane lasts until the
    lane's next transition, the last one until ``end``; idle spans are dropped."""
    if lane.size == 0:
        return []
    order = np.lexsort((time, lane))  # by lane, then time (stable for equal times)
    lane, time, code = lane[order], time[order], code[order]
    until = np.empty_like(time)
    until[:-1] = time[1:]
    last = np.ones(lane.size, bool)
    last[:-1] = lane[1:] != lane[:-1]
    until[last] = np.maximum(end, time[last])
    keep = code != 0
    return np.column_stack([lane[keep], np.round(time[keep], 4), np.round(until[keep], 4),
                            code[keep]]).tolist()


def from_btlog(log: BtLog, offset: float, end: float) -> Timeline:
    """The timeline of a read ``.btlog``; ``offset`` is the clock time of the log's first
    timestamp."""
    index = {n.uid: i for i, n in enumerate(log.nodes)}
    lanes = [{"name": n.name, "path": n.path, "depth": n.depth, "tag": n.tag}
             for n in log.nodes]
    lane = np.array([index[int(u)] for u in log.uid], dtype=np.int64)
    seg = segments(lane, log.time + offset, log.status.astype(np.int64), end)
    return Timeline("tree.btlog", lanes, seg, truncated=log.truncated)


def btlog_offset(log: BtLog, events: Sequence[dict[str, Any]]) -> float:
    """Clock time of the log's time 0: aligned on the first ``tree`` event when the events
    have one (both record the first tick), else 0."""
    first_event = next((e["t"] for e in events if e.get("kind") == "tree"), None)
    if first_event is None or log.time.size == 0:
        return 0.0
    return float(first_event) - float(log.time[0])


def from_events(events: Sequence[dict[str, Any]], end: float) -> Timeline:
    """The timeline of the ``tree`` events of events.jsonl (path, old, new)."""
    tree = [e for e in events if e.get("kind") == "tree" and "path" in e]
    order: dict[str, int] = {}
    for e in tree:
        parts = e["path"].split("/")
        for k in range(1, len(parts) + 1):  # parents get a lane even if never logged
            order.setdefault("/".join(parts[:k]), len(order))
    # Pre-order: each lane right after its parent, siblings in order of first appearance.
    children: dict[str, list[str]] = {}
    for path in order:
        children.setdefault(path.rpartition("/")[0], []).append(path)
    paths: list[str] = []
    stack = list(reversed(children.get("", [])))
    while stack:
        path = stack.pop()
        paths.append(path)
        stack.extend(reversed(children.get(path, [])))
    index = {p: i for i, p in enumerate(paths)}
    lanes = [{"name": p.rpartition("/")[2], "path": p, "depth": p.count("/"), "tag": ""}
             for p in paths]
    lane = np.array([index[e["path"]] for e in tree], dtype=np.int64)
    time = np.array([e["t"] for e in tree], dtype=np.float64)
    code = np.array([CODES.get(e.get("new"), 0) for e in tree], dtype=np.int64)
    return Timeline("events.jsonl", lanes, segments(lane, time, code, end))
