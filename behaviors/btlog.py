"""The tick log: a tree's status transitions in BehaviorTree.CPP's FileLogger2 format.

Groot2 replays a ``.btlog`` file; every flight writes one (``tree.btlog``) with the
simulated clock's timestamps. The layout, byte for byte as BehaviorTree.CPP 4.x writes it
(``bt_file_logger_v2.h``), all integers little-endian:

============  =====  ==================================================================
offset        bytes  what
============  =====  ==================================================================
0             18     ``BTCPP4-FileLogger2`` (ASCII, no terminator)
18            1      protocol version, 1
19            4      N, int32: length of the tree's XML
23            N      the tree's XML (UTF-8): BehaviorTree.CPP v4 ``<root>`` with a
                     ``_uid`` attribute on every node (see :mod:`behaviors.treexml`)
23 + N        8      first timestamp, int64 microseconds (the clock's time when the log
                     was opened: 0 for a lockstep flight's simulated clock)
31 + N + 9k   9      transition k: 6 bytes unsigned microseconds since the first
                     timestamp, 2 bytes uint16 node uid, 1 byte status
============  =====  ==================================================================

Statuses are BehaviorTree.CPP's ``NodeStatus``: 0 IDLE (py_trees' INVALID), 1 RUNNING,
2 SUCCESS, 3 FAILURE, 4 SKIPPED. Node uids are numbered 1, 2, ... in depth-first
pre-order (each node before its children, children in order), the order in which
BehaviorTree.CPP creates them and the ``_uid`` the XML carries.

Each tick's transitions are written and flushed when the tick ends, so a flight that is
cut short leaves a log that is whole up to its last tick; :func:`read_btlog` also reads a
file that ends in the middle of a record (``truncated`` is then True).

Python API::

    from behaviors.btlog import read_btlog
    log = read_btlog("out/demo/tree.btlog")
    log.nodes[7].name, [(t.time, t.uid, t.status.name) for t in log.transitions[:3]]
"""

from __future__ import annotations

import enum
import operator
import os
import struct
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import BinaryIO

import py_trees

from behaviors.treexml import preorder

MAGIC = b"BTCPP4-FileLogger2"
"""The first bytes of a FileLogger2 file."""
PROTOCOL = 1
"""The protocol byte BehaviorTree.CPP 4.x writes after :data:`MAGIC`."""
TRANSITION_SIZE = 9
"""Bytes per transition record."""
_MAX_OFFSET_US = (1 << 48) - 1  # six bytes of microseconds: some 8.9 years
_STATUS = operator.attrgetter("status")


class NodeStatus(enum.IntEnum):
    """BehaviorTree.CPP's ``NodeStatus`` codes as stored in a transition."""

    IDLE = 0
    RUNNING = 1
    SUCCESS = 2
    FAILURE = 3
    SKIPPED = 4


_FROM_PY_TREES = {
    py_trees.common.Status.INVALID: NodeStatus.IDLE,
    py_trees.common.Status.RUNNING: NodeStatus.RUNNING,
    py_trees.common.Status.SUCCESS: NodeStatus.SUCCESS,
    py_trees.common.Status.FAILURE: NodeStatus.FAILURE,
}


def node_status(status: py_trees.common.Status) -> NodeStatus:
    """The BehaviorTree.CPP status of a py_trees status (INVALID is IDLE)."""
    return _FROM_PY_TREES[status]


@dataclass(frozen=True, slots=True)
class Transition:
    """One status change: ``time`` in seconds since the log's first timestamp."""

    time: float
    uid: int
    status: NodeStatus


@dataclass(frozen=True, slots=True)
class LoggedNode:
    """A node of the logged tree's XML: its uid, element tag (the registered node ID,
    e.g. ``Sequence`` or ``NavigateToWaypoint``; ``SubTree`` for a subtree reference), its
    instance name, the uid of its parent (None for a tree's root), and its attributes."""

    uid: int
    tag: str
    name: str
    parent: int | None
    attributes: dict[str, str] = field(default_factory=dict)


@dataclass
class TickLog:
    """A read ``.btlog`` (see :func:`read_btlog`).

    Attributes:
        xml: the tree's XML as stored.
        first_timestamp: seconds (the clock's time when the log was opened).
        transitions: every whole transition record, in file order.
        nodes: the XML's nodes by uid.
        truncated: the file ended inside a record (an interrupted flight); the partial
            record is left out.
    """

    xml: str
    first_timestamp: float
    transitions: list[Transition]
    nodes: dict[int, LoggedNode]
    truncated: bool = False

    def statuses_at(self, time: float) -> dict[int, NodeStatus]:
        """Every node's status after the transitions up to ``time`` (s since the first
        timestamp); nodes never logged are IDLE."""
        status = dict.fromkeys(self.nodes, NodeStatus.IDLE)
        for transition in self.transitions:
            if transition.time > time:
                break
            status[transition.uid] = transition.status
        return status


class BtlogError(ValueError):
    """The file is not a FileLogger2 log (bad header, or shorter than its header)."""


def parse_nodes(xml: str) -> dict[int, LoggedNode]:
    """The nodes carrying a ``_uid`` in a tree XML, by uid (parents found through the
    nesting and, for subtrees, the ``_fullpath`` of their ``<BehaviorTree>``)."""
    root = ET.fromstring(xml)
    nodes: dict[int, LoggedNode] = {}
    subtree_parent: dict[str, int] = {}

    def walk(element: ET.Element, parent: int | None) -> None:
        uid_text = element.get("_uid")
        here = parent
        if uid_text is not None:
            here = int(uid_text)
            attributes = {k: v for k, v in element.attrib.items() if k != "_uid"}
            name = element.get("name") or element.get("ID") or element.tag
            nodes[here] = LoggedNode(here, element.tag, name, parent, attributes)
            if element.tag == "SubTree" and element.get("_fullpath") is not None:
                subtree_parent[element.get("_fullpath", "")] = here
        for child in element:
            walk(child, here)

    for tree in root.findall("BehaviorTree"):
        path = tree.get("_fullpath", "")
        walk(tree, subtree_parent.get(path) if path else None)
    return nodes


def read_btlog(path: str | os.PathLike[str]) -> TickLog:
    """Read a FileLogger2 ``.btlog`` written by this project or by BehaviorTree.CPP.

    Raises:
        BtlogError: not a FileLogger2 file, cut short before its first timestamp, or a
            transition with no node status.
        OSError: the file cannot be read.
    """
    with open(path, "rb") as handle:
        data = handle.read()
    head = len(MAGIC) + 1
    if data[: len(MAGIC)] != MAGIC or len(data) < head + 4:
        raise BtlogError(f"{os.fspath(path)}: not a BehaviorTree.CPP FileLogger2 log")
    if data[len(MAGIC)] != PROTOCOL:
        raise BtlogError(f"{os.fspath(path)}: FileLogger2 protocol {data[len(MAGIC)]}, "
                         f"expected {PROTOCOL}")
    (size,) = struct.unpack_from("<i", data, head)
    start = head + 4 + size
    if size < 0 or len(data) < start + 8:
        raise BtlogError(f"{os.fspath(path)}: cut short inside its header")
    xml = data[head + 4:start].decode("utf-8")
    (first,) = struct.unpack_from("<q", data, start)
    body = data[start + 8:]
    whole = len(body) // TRANSITION_SIZE
    transitions = []
    for k in range(whole):
        record = body[k * TRANSITION_SIZE:(k + 1) * TRANSITION_SIZE]
        micros = int.from_bytes(record[:6], "little")
        uid, status = struct.unpack_from("<HB", record, 6)
        try:
            transitions.append(Transition(micros * 1e-6, uid, NodeStatus(status)))
        except ValueError:
            raise BtlogError(f"{os.fspath(path)}: transition {k} has status {status}, "
                             "which is no node status (a corrupt log, or one caught "
                             "mid-write)") from None
    return TickLog(xml, first * 1e-6, transitions, parse_nodes(xml),
                   truncated=len(body) % TRANSITION_SIZE != 0)


def header_bytes(xml: str, first_timestamp: float) -> bytes:
    """Everything a FileLogger2 file holds before its first transition."""
    text = xml.encode("utf-8")
    return (MAGIC + bytes([PROTOCOL]) + struct.pack("<i", len(text)) + text
            + struct.pack("<q", round(first_timestamp * 1e6)))


def transition_bytes(offset: float, uid: int, status: NodeStatus) -> bytes:
    """One transition record, ``offset`` seconds after the first timestamp."""
    micros = min(max(round(offset * 1e6), 0), _MAX_OFFSET_US)
    return micros.to_bytes(6, "little") + struct.pack("<HB", uid, int(status))


class _Visitor(py_trees.visitors.VisitorBase):
    """Sees each ticked node right after its status was set, in tick order."""

    def __init__(self, seen: Callable[[py_trees.behaviour.Behaviour], None]) -> None:
        super().__init__(full=False)
        self.run = seen


class TickLogger:
    """Writes a py_trees tree's status transitions to a ``.btlog`` while it is ticked.

    Attach with :meth:`attach` before the first tick. During a tick each node's new status
    is logged as the node returns it (so a child's SUCCESS comes before its parent's);
    after the tick, nodes that a parent stopped (reset to IDLE) are logged too. Each tick's
    records are flushed when the tick ends. Nothing it does changes the tree.

    Args:
        path: the ``.btlog`` file (created or replaced).
        root: the tree's root.
        xml: the tree's XML with ``_uid`` attributes
            (:func:`behaviors.treexml.instance_xml`; uids follow
            :func:`behaviors.treexml.preorder`).
        now: the clock (seconds); its value now is the first timestamp.
    """

    def __init__(self, path: str | os.PathLike[str], root: py_trees.behaviour.Behaviour,
                 xml: str, now: Callable[[], float]) -> None:
        self.now = now
        self.first = float(now())
        self.nodes = list(preorder(root))
        if len(self.nodes) > 0xFFFF:
            raise ValueError(f"{len(self.nodes)} nodes: a .btlog numbers at most 65535")
        self.uid = {id(node): i + 1 for i, node in enumerate(self.nodes)}
        self.seen = [py_trees.common.Status.INVALID] * len(self.nodes)  # as last logged
        self.pending = bytearray()
        self.transitions = 0
        self.file: BinaryIO | None = open(path, "wb")  # noqa: SIM115 - closed by close()
        self.file.write(header_bytes(xml, self.first))
        self.file.flush()

    def attach(self, tree: py_trees.trees.BehaviourTree) -> TickLogger:
        """Log ``tree`` (whose root this logger was made for) from its next tick on."""
        tree.visitors.append(_Visitor(self._seen))
        tree.add_post_tick_handler(self._after_tick)
        return self

    def _log(self, index: int, status: py_trees.common.Status) -> None:
        self.seen[index] = status
        self.pending += transition_bytes(self.now() - self.first, index + 1,
                                         _FROM_PY_TREES[status])
        self.transitions += 1

    def _seen(self, node: py_trees.behaviour.Behaviour) -> None:
        uid = self.uid.get(id(node))
        if uid is not None and node.status is not self.seen[uid - 1]:
            self._log(uid - 1, node.status)

    def _after_tick(self, tree: py_trees.trees.BehaviourTree) -> None:
        # One pass in C over the statuses; Python only for the nodes a parent stopped.
        now = list(map(_STATUS, self.nodes))
        if now != self.seen:
            for index, (old, new) in enumerate(zip(self.seen, now, strict=True)):
                if new is not old:
                    self._log(index, new)
        self.flush()

    def flush(self) -> None:
        """Write the records logged so far."""
        if self.file is not None and self.pending:
            self.file.write(self.pending)
            self.file.flush()
            self.pending.clear()

    def close(self) -> None:
        """Flush and close the file (the tree may go on ticking; nothing more is logged)."""
        if self.file is not None:
            self.flush()
            self.file.close()
            self.file = None
