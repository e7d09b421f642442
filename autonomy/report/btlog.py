"""Reading a tree's tick log in BehaviorTree.CPP's FileLogger2 format (``.btlog``).

Layout (BehaviorTree.CPP ``loggers/bt_file_logger_v2.h``, all integers little-endian):

- the text ``BTCPP4-FileLogger2`` and one protocol byte (1); files without this header,
  starting directly at the next field, are read too;
- uint32 N, then N bytes: the tree as BehaviorTree.CPP v4 XML, each node carrying a ``_uid``
  attribute (and ``_fullpath``);
- int64: the first timestamp, microseconds since the Unix epoch;
- 9 bytes per transition: a 6-byte time since the first timestamp in microseconds, the
  node's uint16 uid, one status byte (BehaviorTree.CPP writes the new status, 0 IDLE,
  1 RUNNING, 2 SUCCESS, 3 FAILURE, 4 SKIPPED; a writer may put the previous status in the
  high nibble, which is ignored: the previous status is the node's last logged one).

A log cut short (a flight that was killed) is read up to its last complete transition and
marked ``truncated``; only a log cut inside its XML cannot be read.
"""

from __future__ import annotations

import struct
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from autonomy.errors import UserError

MAGIC = b"BTCPP4-FileLogger2"
STATUS_NAMES = ("IDLE", "RUNNING", "SUCCESS", "FAILURE", "SKIPPED")
TRANSITION = np.dtype([("dt", "u1", (6,)), ("uid", "<u2"), ("status", "u1")])
assert TRANSITION.itemsize == 9


@dataclass(frozen=True)
class BtNode:
    """One node of the logged tree: its uid, the name shown, its XML tag, its path of names
    from the root (``/``-joined) and its depth (root 0)."""

    uid: int
    name: str
    tag: str
    path: str
    depth: int


@dataclass
class BtLog:
    """A read ``.btlog``.

    Attributes:
        xml: the tree's XML as logged.
        first_timestamp_us: microseconds since the Unix epoch of time 0 of the transitions.
        nodes: the tree's nodes in depth-first order.
        time: (N,) seconds since the first timestamp of each transition.
        uid: (N,) node uid of each transition.
        status: (N,) new status code (see :data:`STATUS_NAMES`).
        truncated: the file ended inside a transition or before the first timestamp.
    """

    xml: str
    first_timestamp_us: int
    nodes: list[BtNode]
    time: np.ndarray
    uid: np.ndarray
    status: np.ndarray
    truncated: bool = False
    unknown_uids: int = 0  # transitions naming a uid the XML lacks (left out)
    by_uid: dict[int, BtNode] = field(default_factory=dict, repr=False)


def read_btlog(path: str | Path) -> BtLog:
    """Read a ``.btlog`` file; raises :class:`UserError` (file and reason) when it is not one
    or is cut inside its header."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise UserError(f"{path}: cannot read the tree log ({exc.strerror or exc})") from None
    return parse_btlog(data, str(path))


def parse_btlog(data: bytes, name: str = "tree.btlog") -> BtLog:
    """:func:`read_btlog` on bytes; ``name`` is used in error messages."""
    pos = 0
    if data.startswith(MAGIC):
        pos = len(MAGIC) + 1  # the protocol byte
    if len(data) < pos + 4:
        raise UserError(f"{name}: not a BehaviorTree.CPP tree log (.btlog): shorter than its "
                        "header")
    (size,) = struct.unpack_from("<I", data, pos)
    pos += 4
    if size > len(data) - pos:
        raise UserError(f"{name}: not a complete .btlog: its tree XML claims {size} bytes, "
                        f"{len(data) - pos} follow")
    xml = data[pos:pos + size].decode("utf-8", "replace")
    pos += size
    nodes = _nodes(xml, name)
    by_uid = {n.uid: n for n in nodes}
    empty = np.zeros(0)
    if len(data) < pos + 8:  # stopped before anything was ticked
        return BtLog(xml, 0, nodes, empty, empty.astype(np.uint16), empty.astype(np.uint8),
                     truncated=True, by_uid=by_uid)
    (first,) = struct.unpack_from("<q", data, pos)
    pos += 8
    count, rest = divmod(len(data) - pos, TRANSITION.itemsize)
    records = np.frombuffer(data, TRANSITION, count=count, offset=pos)
    stamps = np.zeros((count, 8), np.uint8)
    stamps[:, :6] = records["dt"]
    time = stamps.view("<u8").ravel().astype(np.float64) / 1e6
    uid = records["uid"].astype(np.uint16)
    status = (records["status"] & 0x0F).astype(np.uint8)
    known = np.isin(uid, np.fromiter(by_uid, np.uint16, len(by_uid)))
    known &= status < len(STATUS_NAMES)
    return BtLog(xml, int(first), nodes, time[known], uid[known], status[known],
                 truncated=rest != 0, unknown_uids=int((~known).sum()), by_uid=by_uid)


def _nodes(xml: str, name: str) -> list[BtNode]:
    """The nodes of the main tree in depth-first order, by their ``_uid`` attributes (or
    numbered 1, 2, ... in document order when the XML has none)."""
    try:
        root = ET.fromstring(xml)
    except ET.ParseError as exc:
        raise UserError(f"{name}: the tree XML in the log does not parse ({exc})") from None
    trees = root.findall("BehaviorTree") if root.tag == "root" else [root]
    main = root.get("main_tree_to_execute")
    trees.sort(key=lambda t: t.get("ID") != main)  # the main tree first
    nodes: list[BtNode] = []
    has_uids = any(el.get("_uid") is not None for t in trees for el in t.iter())

    def visit(element: ET.Element, parents: list[str]) -> None:
        label = element.get("name") or element.get("ID") or element.tag
        path = [*parents, label]
        uid = element.get("_uid")
        if uid is not None or not has_uids:
            if uid is not None and not uid.isdigit():
                raise UserError(f"{name}: node {label!r} has a _uid that is not a number: "
                                f"{uid!r}")
            nodes.append(BtNode(
                uid=int(uid) if uid is not None else len(nodes) + 1, name=label,
                tag=element.tag, path="/".join(path), depth=len(parents),
            ))
        for child in element:
            visit(child, path)

    for tree in trees:
        for child in tree:
            visit(child, [])
    return nodes
