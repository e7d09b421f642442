"""Text renderings of a mission tree: ASCII for terminals and logs, Graphviz dot for docs.

The dot text is written here from the tree structure so that no Graphviz binary is needed
(``dot -Tsvg mission.dot -o mission.svg`` renders it where Graphviz is installed).
"""

from __future__ import annotations

import os

import py_trees
from py_trees.common import Status

# Graphviz node style per node kind, after py_trees.display.dot_tree.
_STYLE = {
    "Selector": ("octagon", "cyan"),
    "Sequence": ("box", "orange"),
    "Parallel": ("parallelogram", "gold"),
    "Decorator": ("ellipse", "ghostwhite"),
    "Behaviour": ("ellipse", "gray"),
}
_STATUS_COLOUR = {
    Status.SUCCESS: "green",
    Status.FAILURE: "red",
    Status.RUNNING: "blue",
}


def _root(tree: py_trees.trees.BehaviourTree | py_trees.behaviour.Behaviour):
    return tree.root if isinstance(tree, py_trees.trees.BehaviourTree) else tree


def render_ascii(
    tree: py_trees.trees.BehaviourTree | py_trees.behaviour.Behaviour, show_status: bool = False
) -> str:
    """The tree as indented ASCII text (py_trees.display.ascii_tree), optionally with each
    node's last status."""
    return py_trees.display.ascii_tree(_root(tree), show_status=show_status)


def _kind(node: py_trees.behaviour.Behaviour) -> str:
    if isinstance(node, py_trees.composites.Selector):
        return "Selector"
    if isinstance(node, py_trees.composites.Sequence):
        return "Sequence"
    if isinstance(node, py_trees.composites.Parallel):
        return "Parallel"
    if isinstance(node, py_trees.decorators.Decorator):
        return "Decorator"
    return "Behaviour"


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def dot_text(
    tree: py_trees.trees.BehaviourTree | py_trees.behaviour.Behaviour, show_status: bool = False
) -> str:
    """The tree as Graphviz dot source: sequences as boxes, selectors as octagons,
    decorators and behaviours as ellipses, each labelled with its name and class; with
    ``show_status`` the outline is coloured by the node's last status."""
    lines = [
        "digraph mission {",
        "  graph [fontname=Helvetica, rankdir=TB, ordering=out];",
        "  node [fontname=Helvetica, style=filled, fontsize=11];",
    ]
    ids: dict[int, str] = {}
    for index, node in enumerate(_root(tree).iterate()):
        ids[id(node)] = f"n{index}"
    for node in _root(tree).iterate():
        shape, fill = _STYLE[_kind(node)]
        label = _quote(node.name)[:-1] + f"\\n({type(node).__name__})" + '"'
        attributes = f"label={label}, shape={shape}, fillcolor={fill}"
        if show_status and node.status in _STATUS_COLOUR:
            attributes += f", color={_STATUS_COLOUR[node.status]}, penwidth=3"
        lines.append(f"  {ids[id(node)]} [{attributes}];")
    for node in _root(tree).iterate():
        for child in node.children:
            lines.append(f"  {ids[id(node)]} -> {ids[id(child)]};")
    lines.append("}")
    return "\n".join(lines) + "\n"


def write_dot(
    tree: py_trees.trees.BehaviourTree | py_trees.behaviour.Behaviour,
    path: str | os.PathLike[str],
    show_status: bool = False,
) -> str:
    """Write :func:`dot_text` of the tree to ``path``; returns the path written."""
    text = dot_text(tree, show_status=show_status)
    with open(path, "w", encoding="utf-8") as handle:
        handle.write(text)
    return os.fspath(path)
