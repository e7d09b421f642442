"""BehaviorTree.CPP v4 XML of a built (instantiated) py_trees tree.

:func:`instance_xml` writes what BehaviorTree.CPP's ``WriteTreeToXML`` writes for a
running tree, the XML that heads a ``.btlog`` (:mod:`behaviors.btlog`): one
``<BehaviorTree>`` per tree or subtree instance, every node as
``<ID name="..." _uid="N" port="value" .../>`` with uids in depth-first pre-order from 1,
subtree references as ``<SubTree ID="..." _fullpath="..." _uid="N"/>`` with the subtree's
nodes in their own ``<BehaviorTree _fullpath="...">``, then a ``<TreeNodesModel>``.

Nodes built from XML by :mod:`behaviors.loader` carry their registered ID and port values
(``bt_id``, ``bt_ports``, ``bt_subtree``); any other py_trees node is named after its
class (py_trees composites after their BehaviorTree.CPP equivalents), without ports.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from collections.abc import Iterable

import py_trees

from behaviors import ticking

MAIN_TREE = "LandingMission"
"""The ID of the main ``<BehaviorTree>`` when a tree does not say."""


def bt_id(node: py_trees.behaviour.Behaviour) -> str:
    """The BehaviorTree.CPP node ID of a built node: the registered ID it was built from,
    else the equivalent of its py_trees class (memory Sequence/Selector are BT.CPP's
    ``Sequence``/``Fallback``, memory-less ones ``ReactiveSequence``/``ReactiveFallback``,
    ``Retry`` is ``RetryUntilSuccessful``), else its class name."""
    known = getattr(node, "bt_id", None)
    if known:
        return known
    if isinstance(node, py_trees.composites.Sequence):
        return "Sequence" if node.memory else "ReactiveSequence"
    if isinstance(node, py_trees.composites.Selector):
        return "Fallback" if node.memory else "ReactiveFallback"
    if isinstance(node, py_trees.composites.Parallel):
        return "Parallel"
    if type(node) in (py_trees.decorators.Retry, ticking.Retry):
        return "RetryUntilSuccessful"
    if type(node) in (py_trees.decorators.Inverter, ticking.Inverter):
        return "Inverter"
    return type(node).__name__


def instance_xml(
    tree: py_trees.trees.BehaviourTree | py_trees.behaviour.Behaviour,
    models: ET.Element | None = None,
    main_tree: str | None = None,
) -> str:
    """The XML of a built tree with a ``_uid`` on every node (see the module docstring).

    Args:
        tree: the tree or its root.
        models: a ``<TreeNodesModel>`` element to append (default: an empty one).
        main_tree: the main tree's ID (default: the root's ``bt_tree`` or
            :data:`MAIN_TREE`).
    """
    root_node = tree.root if isinstance(tree, py_trees.trees.BehaviourTree) else tree
    main = main_tree or getattr(root_node, "bt_tree", None) or MAIN_TREE
    document = ET.Element("root", {"BTCPP_format": "4", "main_tree_to_execute": main})
    uid = 0
    blocks: list[ET.Element] = []  # the main tree first, then each subtree as met

    def add(node: py_trees.behaviour.Behaviour, parent: ET.Element, prefix: str) -> None:
        nonlocal uid
        uid += 1
        subtree = getattr(node, "bt_subtree", None)
        if subtree is not None:
            # BT.CPP's path of a subtree instance: its name, or ID::uid when unnamed
            path = prefix + (f"{subtree}::{uid}" if node.name == subtree else node.name)
            element = ET.SubElement(parent, "SubTree",
                                    {"ID": subtree, "_fullpath": path, "_uid": str(uid)})
            block = ET.Element("BehaviorTree", {"ID": subtree, "_fullpath": path})
            blocks.append(block)
            # BT.CPP numbers a subtree's nodes right after its SubTree node.
            for child in node.children:
                add(child, block, path + "/")
            return
        element = ET.SubElement(parent, bt_id(node), {"name": node.name, "_uid": str(uid)})
        for port, value in getattr(node, "bt_ports", {}).items():
            element.set(port, value)
        for child in node.children:
            add(child, element, prefix)

    main_block = ET.Element("BehaviorTree", {"ID": main, "_fullpath": ""})
    blocks.append(main_block)
    add(root_node, main_block, "")
    document.extend(blocks)
    document.append(models if models is not None else ET.Element("TreeNodesModel"))
    return to_text(document)


def to_text(document: ET.Element) -> str:
    """An element as indented XML text with an XML declaration, ending in a newline."""
    ET.indent(document, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(
        document, encoding="unicode") + "\n"


def preorder(root: py_trees.behaviour.Behaviour) -> Iterable[py_trees.behaviour.Behaviour]:
    """The nodes of a tree in uid order (depth-first pre-order)."""
    stack = [root]
    while stack:
        node = stack.pop()
        yield node
        stack.extend(reversed(node.children))


def source_xml(document, models: ET.Element | None = None) -> str:
    """A tree file's text as read (:class:`behaviors.loader.TreeDocument`), written back
    in the canonical layout with ``models`` (default: every registered node) as its
    ``<TreeNodesModel>``: what ``lander tree --xml`` writes and Groot2 opens."""
    from behaviors.registry import models_element

    def element(node) -> ET.Element:
        out = ET.Element(node.tag, dict(node.attrib))
        out.extend(element(child) for child in node.children)
        return out

    root = ET.Element("root", {"BTCPP_format": "4", "main_tree_to_execute": document.main})
    root.extend(element(tree) for tree in document.trees.values())
    root.append(models if models is not None else models_element())
    return to_text(root)
