"""What a flight records of its tree: ``tree.btlog`` (:mod:`behaviors.btlog`, for Groot2)
and ``blackboard.jsonl`` (:mod:`behaviors.bblog`), written as the tree is ticked."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable
from pathlib import Path

import py_trees

from behaviors import blackboard as keys
from behaviors.bblog import BlackboardLogger
from behaviors.btlog import TickLogger
from behaviors.registry import models_element
from behaviors.treexml import instance_xml

TICK_LOG = "tree.btlog"
BLACKBOARD_LOG = "blackboard.jsonl"


class TreeRecorder:
    """Logs a tree's transitions and blackboard changes into ``directory`` from its next
    tick on; :meth:`close` when the flight ends (an unclosed log is still whole up to its
    last tick).

    Args:
        tree: the built tree, not ticked yet.
        directory: where ``tree.btlog`` and ``blackboard.jsonl`` are written.
        now: the clock (seconds); the simulated clock in lockstep.
        extra_keys: blackboard keys to log besides the mission's own
            (:data:`behaviors.blackboard.KEYS`).
    """

    def __init__(self, tree: py_trees.trees.BehaviourTree, directory: str | os.PathLike[str],
                 now: Callable[[], float], extra_keys: Iterable[str] = ()) -> None:
        directory = Path(directory)
        xml = instance_xml(tree, models=models_element())
        self.ticks = TickLogger(directory / TICK_LOG, tree.root, xml, now).attach(tree)
        followed = list(dict.fromkeys([*keys.KEYS, *extra_keys,
                                       *getattr(tree, "blackboard_keys", ())]))
        self.board = BlackboardLogger(directory / BLACKBOARD_LOG, followed, now).attach(tree)

    def close(self) -> None:
        self.ticks.close()
        self.board.close()

