"""The tree's timeline for report.html: which node ran when, with which status.

Built from the flight's ``tree.btlog`` (BehaviorTree.CPP FileLogger2, read by
:func:`behaviors.btlog.read_btlog`) when there is one, else from the ``tree`` events of
events.jsonl. Either way the result is a list of lanes (one per node, parents before their
children) and segments ``[lane, start, end, status]``: the node held ``status`` from
``start`` to ``end`` (clock seconds); idle/invalid time is no segment.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from behaviors.btlog import TickLog

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
    """Segments from transitions (any order; equal times keep their order): each transition
    of a lane lasts until the lane's next transition, the last one until ``end``."""
    if lane.size == 0:
        return []
    order = np.lexsort((time, lane))  # by lane, then time (stable for equal times)
    lane, time, code = lane[order], time[order], code[order]
    until = np.empty_like(time)
    until[:-1] = time[1:]
    last = np.ones(lane.size, bool)
    last[:-1] = lane[1:] != lane[:-1]
    until[last] = np.maximum(end, time[last])
    # Idle is no bar; neither is a status replaced within the same tick (RUNNING then
    # SUCCESS at one instant shows as the SUCCESS).
    keep = (code != 0) & ((until > time) | last)
    return np.column_stack([lane[keep], np.round(time[keep], 4), np.round(until[keep], 4),
                            code[keep]]).tolist()


def from_btlog(log: TickLog, end: float) -> Timeline:
    """The timeline of a read ``.btlog`` (its first timestamp is the clock's time when it
    was opened, so its times are clock times once added to it)."""
    uids = sorted(log.nodes)
    names: dict[int, str] = {}

    def path(uid: int) -> str:
        if uid not in names:
            node = log.nodes[uid]
            parent = node.parent if node.parent in log.nodes else None
            names[uid] = node.name if parent is None else f"{path(parent)}/{node.name}"
        return names[uid]

    def depth(uid: int) -> int:
        parent = log.nodes[uid].parent
        return 0 if parent not in log.nodes else 1 + depth(parent)

    index = {uid: i for i, uid in enumerate(uids)}
    lanes = [{"name": log.nodes[u].name, "path": path(u), "depth": depth(u),
              "tag": log.nodes[u].tag} for u in uids]
    known = [t for t in log.transitions if t.uid in index]
    lane = np.array([index[t.uid] for t in known], dtype=np.int64)
    time = np.array([t.time for t in known], dtype=np.float64) + log.first_timestamp
    code = np.array([int(t.status) for t in known], dtype=np.int64)
    return Timeline("tree.btlog", lanes, segments(lane, time, code, end),
                    truncated=log.truncated)


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
