"""Trees from BehaviorTree.CPP v4 XML files: read, check against the node registry and a
mission, build as py_trees.

A tree file is ``<root BTCPP_format="4" main_tree_to_execute="ID">`` holding one or more
``<BehaviorTree ID="...">`` (each with one root node) and optionally a
``<TreeNodesModel>`` (ignored when reading: the registry is the model). Nodes are written
in the compact form ``<Land name="..." phase="land"/>`` or the explicit one
``<Action ID="Land" .../>``; ``name`` defaults to the ID. Port values are literals, mission
settings or blackboard entries (:mod:`behaviors.registry`). Beyond BehaviorTree.CPP:

* ``_skipIf="SETTING"`` / ``_skipIf="!SETTING"`` with a true/false mission setting leaves
  the node out of the built tree when it holds (BehaviorTree.CPP would skip it on every
  tick; the setting is fixed for the flight, so leaving it out is the same);
* ``MissionWaypoints`` repeats its child once per mission waypoint (see the registry).

Every problem is reported as one line ``FILE:LINE: NODE 'NAME': port PORT: REASON``.
"""

from __future__ import annotations

import re
import xml.parsers.expat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import py_trees

from behaviors import blackboard as keys
from behaviors.names import did_you_mean
from behaviors.registry import (
    PARSERS,
    REGISTRY,
    SERVICES,
    BuildContext,
    NodeModel,
    PortValueError,
    accepts,
    blackboard_key,
    format_value,
    type_of,
)

BUILTIN_TREE = Path(__file__).with_name("landing_tree.xml")
"""The built-in landing tree, the one every mission flies unless it names ``tree:``."""

MAX_DEPTH = 256
"""Elements nest at most this deep, as in BehaviorTree.CPP."""

MAX_TREE_BYTES = 5_000_000
"""A tree file is at most 5 MB (the built-in one is 5 kB)."""

_EXPLICIT = ("Action", "Condition", "Control", "Decorator")
_ALIASES = {"Selector": "Fallback", "ReactiveSelector": "ReactiveFallback",
            "Retry": "RetryUntilSuccessful", "Timeout": "ClockTimeout"}
_IGNORED = ("_uid", "_fullpath", "_autoremap", "_description")


class TreeFileError(ValueError):
    """A tree file with problems; ``problems`` holds one line each."""

    def __init__(self, problems: list[str]) -> None:
        self.problems = problems
        super().__init__("\n".join(problems))


@dataclass
class XmlNode:
    """An XML element with the line it starts on."""

    tag: str
    attrib: dict[str, str]
    line: int
    children: list[XmlNode] = field(default_factory=list)


@dataclass
class TreeDocument:
    """A parsed tree file: its name (for messages), its ``<root>``, its trees by ID and
    the main tree's ID."""

    name: str
    root: XmlNode
    trees: dict[str, XmlNode]
    main: str


def parse_xml(text: str, name: str) -> XmlNode:
    """Elements of ``text`` with line numbers (expat, which resolves no external
    entities)."""
    parser = xml.parsers.expat.ParserCreate()
    stack: list[XmlNode] = []
    top: list[XmlNode] = []

    def start(tag: str, attrib: dict[str, str]) -> None:
        if len(stack) >= MAX_DEPTH:
            raise TreeFileError([f"{name}:{parser.CurrentLineNumber}: <{tag}>: nested deeper "
                                 f"than {MAX_DEPTH} elements (BehaviorTree.CPP's limit)"])
        node = XmlNode(tag, dict(attrib), parser.CurrentLineNumber)
        (stack[-1].children if stack else top).append(node)
        stack.append(node)

    parser.StartElementHandler = start
    parser.EndElementHandler = lambda tag: stack.pop()
    parser.ordered_attributes = False
    try:
        parser.Parse(text, True)
    except xml.parsers.expat.ExpatError as exc:
        reason = xml.parsers.expat.ErrorString(exc.code)
        raise TreeFileError([f"{name}:{exc.lineno}: XML syntax error: {reason}"]) from None
    return top[0]


def parse_tree(text: str, name: str) -> TreeDocument:
    """The trees of a tree file's text; ``name`` is used in messages."""
    root = parse_xml(text, name)
    where = f"{name}:{root.line}"
    if root.tag != "root":
        raise TreeFileError([f"{where}: the document element must be <root>, not "
                             f"<{root.tag}>"])
    if root.attrib.get("BTCPP_format") != "4":
        raise TreeFileError([f"{where}: <root> needs BTCPP_format=\"4\" (BehaviorTree.CPP "
                             "v4 XML)"])
    problems: list[str] = []
    trees: dict[str, XmlNode] = {}
    for child in root.children:
        if child.tag == "TreeNodesModel":
            continue
        if child.tag != "BehaviorTree":
            problems.append(f"{name}:{child.line}: <{child.tag}>: <root> holds "
                            "<BehaviorTree> and <TreeNodesModel> elements only")
            continue
        tree_id = child.attrib.get("ID", "")
        if not tree_id:
            problems.append(f"{name}:{child.line}: BehaviorTree: needs an ID")
        elif tree_id in trees:
            problems.append(f"{name}:{child.line}: BehaviorTree '{tree_id}': defined twice")
        elif tree_id in REGISTRY:
            problems.append(f"{name}:{child.line}: BehaviorTree '{tree_id}': the ID of a "
                            "registered node")
        elif len(child.children) != 1:
            problems.append(f"{name}:{child.line}: BehaviorTree '{tree_id}': needs exactly "
                            f"one root node, has {len(child.children)}")
        else:
            trees[tree_id] = child
    main = root.attrib.get("main_tree_to_execute")
    if main is None and len(trees) == 1:
        main = next(iter(trees))
    if not problems and not trees:
        problems.append(f"{where}: no <BehaviorTree> in the file")
    elif not problems and main not in trees:
        problems.append(f"{where}: main_tree_to_execute "
                        f"{'is missing' if main is None else repr(main) + ' is not defined'}"
                        f" (trees: {', '.join(trees)})")
    if problems:
        raise TreeFileError(problems)
    return TreeDocument(name, root, trees, main or "")


def read_tree(path: str | Path) -> TreeDocument:
    """Read and parse a tree file (see :func:`parse_tree`)."""
    path = Path(path)
    try:
        size = path.stat().st_size
        if size > MAX_TREE_BYTES:
            raise TreeFileError([f"{path}: cannot read tree file: {size:,} bytes, more than "
                                 f"{MAX_TREE_BYTES:,}"])
        text = path.read_text(encoding="utf-8")
    except (OSError, ValueError) as exc:  # ValueError: not UTF-8, or a NUL in the name
        reason = ("not UTF-8 text" if isinstance(exc, UnicodeDecodeError)
                  else getattr(exc, "strerror", None) or str(exc))
        raise TreeFileError([f"{path}: cannot read tree file: {reason}"]) from None
    return parse_tree(text, str(path))


# --- checking and building ------------------------------------------------------------


class _Builder:
    """One pass over a document: checks every node against the registry and the mission
    settings and, when ``context`` is given, builds it."""

    def __init__(self, document: TreeDocument, settings: dict[str, Any],
                 context: BuildContext | None, services: frozenset[str] = frozenset()) -> None:
        self.doc = document
        self.settings = settings
        self.context = context
        self.services = services if context is None else frozenset(context.services)
        self.problems: list[str] = []
        self.runtime_keys: dict[str, None] = {}  # absolute blackboard keys, in order

    def problem(self, node: XmlNode, what: str, reason: str) -> None:
        self.problems.append(f"{self.doc.name}:{node.line}: {what}: {reason}")

    def model_of(self, node: XmlNode) -> tuple[str, NodeModel | None]:
        node_id = node.attrib.get("ID", "") if node.tag in _EXPLICIT else node.tag
        model = REGISTRY.get(node_id)
        if model is None:
            hint = (f"; BehaviorTree.CPP calls it {_ALIASES[node_id]}" if node_id in _ALIASES
                    else did_you_mean(node_id, REGISTRY))
            self.problem(node, node_id or node.tag, f"unknown node (see `lander tree "
                         f"--xml` for the registered ones){hint}")
        elif node.tag in _EXPLICIT and model.kind != node.tag and node_id != "SubTree":
            self.problem(node, node_id, f"is a {model.kind}, written as <{node.tag}>")
        return node_id, model

    def skipped(self, node: XmlNode, label: str) -> bool:
        condition = node.attrib.get("_skipIf")
        if condition is None:
            return False
        setting = condition.strip().removeprefix("!").strip()
        value = self.settings.get(setting)
        if not isinstance(value, bool):
            self.problem(node, label, f"_skipIf: {condition!r}: only a true/false mission "
                         "setting or its negation (!setting) can be used here")
            return False
        return value != condition.strip().startswith("!")

    def value(self, node: XmlNode, label: str, port, text: str,
              settings: dict[str, Any]) -> tuple[Any, str] | None:
        """(value, text for the instance XML) of a port, or None after a problem."""
        where = f"{label}: port {port.name}"
        bound = re.fullmatch(r"\{([^{}]+)\}", text.strip())
        if bound is not None:
            name = bound.group(1).strip()
            if name in settings:
                setting = settings[name]
                if not accepts(port.type, type_of(setting)):
                    self.problem(node, where, f"{{{name}}} is a {type_of(setting)} mission "
                                 f"setting, the port takes {port.type}")
                    return None
                if port.direction != "input":
                    self.problem(node, where, f"{{{name}}} is a mission setting; an "
                                 f"{port.direction} port needs a blackboard entry")
                    return None
                return self.checked(node, where, port, setting), format_value(setting)
            if not port.runtime:
                hint = _waypoint_hint(name, settings) or (
                    " (this port is fixed when the tree is built: a literal or a mission "
                    "setting such as {navigation_timeout}; see docs/trees.md)")
                self.problem(node, where, f"the mission has no setting {{{name}}}{hint}")
                return None
            key = blackboard_key(name)
            if self.context is not None and key not in self.runtime_keys \
                    and key not in keys.DEFAULTS:
                py_trees.blackboard.Blackboard.set(key, None)  # the tree's own entry: fresh
            self.runtime_keys[key] = None
            return key, f"{{{name}}}"
        if port.direction != "input":
            self.problem(node, where, f"an {port.direction} port takes a blackboard entry "
                         f"{{name}}, not {text!r}")
            return None
        try:
            parsed = PARSERS[port.type](text)
        except PortValueError as exc:
            self.problem(node, where, f"{exc} ({port.type}"
                         f"{', ' + port.unit if port.unit else ''})")
            return None
        return self.checked(node, where, port, parsed), text

    def checked(self, node: XmlNode, where: str, port, value: Any) -> Any:
        if port.type == "double" and port.name in ("seconds",) and not value > 0:
            self.problem(node, where, f"must be > 0 s, got {value}")
        if port.type == "int" and port.name == "num_attempts" and value < 1:
            self.problem(node, where, f"must be >= 1, got {value}")
        if port.name == "phase" and value not in keys.PHASES:
            self.problem(node, where, f"{value!r} is not a phase ({', '.join(keys.PHASES)})")
        return value

    def node(self, node: XmlNode, settings: dict[str, Any], path: tuple[str, ...]
             ) -> list[py_trees.behaviour.Behaviour]:
        """The built node(s) of ``node``: none when skipped, several for an expansion."""
        node_id, model = self.model_of(node)
        if model is None:
            return []
        label = f"{node_id} '{node.attrib['name']}'" if "name" in node.attrib else node_id
        if self.skipped(node, label):
            return []
        for need in model.requires:
            if need not in self.services:
                self.problem(node, label, f"needs {SERVICES[need]}, which this mission does "
                             "not provide")
        if node_id == "SubTree":
            return self.subtree(node, label, path)
        if node_id == "MissionWaypoints":
            return self.waypoints(node, model, label, settings, path)
        low, high = model.children
        count = len(node.children)
        if count < low or (high is not None and count > high):
            want = (f"exactly {low}" if low == high else f"at least {low}"
                    if high is None else f"{low} to {high}")
            self.problem(node, label, f"takes {want} child node{'s' * (want != 'exactly 1')}"
                         f", has {count}")
        children = [built for child in node.children
                    for built in self.node(child, settings, path)]
        if model.kind == "Decorator" and node.children and len(children) != 1:
            if count == 1:  # the child was skipped or is unknown
                self.problem(node, label, "its child is left out (_skipIf) or unknown")
            return []
        if model.kind == "Control" and node.children and not children and not self.problems:
            self.problem(node, label, "every child is left out (_skipIf)")
            return []
        values: dict[str, Any] = {}
        texts: dict[str, str] = {}
        for attribute in node.attrib:
            if attribute in ("name", "ID", "_skipIf") or attribute in _IGNORED:
                continue
            if model.port(attribute) is None:
                ports = ", ".join(p.name for p in model.ports) or "none"
                self.problem(node, f"{label}: port {attribute}",
                             f"{node_id} has no such port (its ports: {ports})")
        for port in model.ports:
            text = node.attrib.get(port.name, port.default)
            if text is None:
                if not port.optional:
                    self.problem(node, f"{label}: port {port.name}",
                                 f"required ({port.type}{', ' + port.unit if port.unit else ''}"
                                 f": {port.description})")
                continue
            resolved = self.value(node, label, port, text, settings)
            if resolved is not None:
                values[port.name], texts[port.name] = resolved
        name = node.attrib.get("name")
        if name is None:
            name = node_id
            if model.default_name is not None and children and len(texts) == len(
                    [p for p in model.ports if p.name in texts]):
                try:
                    name = model.default_name(texts, [c.name for c in children])
                except (KeyError, ValueError):
                    name = node_id
        name = _substitute(name, settings)
        if self.context is None:
            return [_Checked(name)]
        try:
            built = model.build(self.context, name, values, children)
        except ValueError as exc:
            self.problem(node, label, str(exc))
            return []
        built.bt_id = node_id
        built.bt_ports = texts
        return [built]

    def waypoints(self, node: XmlNode, model: NodeModel, label: str,
                  settings: dict[str, Any], path: tuple[str, ...]
                  ) -> list[py_trees.behaviour.Behaviour]:
        if len(node.children) != 1:
            self.problem(node, label, f"takes exactly 1 child node (repeated per waypoint), "
                         f"has {len(node.children)}")
            return []
        copies = []
        for number in range(1, settings["waypoint_count"] + 1):
            each = dict(settings, waypoint=settings[f"waypoint_{number}"],
                        waypoint_number=number)
            copies += self.node(node.children[0], each, path)
            if self.problems:
                return []  # the same problem would repeat for every waypoint
        name = _substitute(node.attrib.get("name", "MissionWaypoints"), settings)
        if self.context is None:
            return [_Checked(name)]
        built = model.build(self.context, name, {}, copies)
        built.bt_id = "Sequence"
        built.bt_ports = {}
        return [built]

    def subtree(self, node: XmlNode, label: str, path: tuple[str, ...]
                ) -> list[py_trees.behaviour.Behaviour]:
        tree_id = node.attrib.get("ID", "")
        extra = [a for a in node.attrib if a not in ("ID", "name", "_skipIf", *_IGNORED)]
        if extra:
            self.problem(node, label + f": port {extra[0]}", "subtrees take no ports: they "
                         "share the mission's blackboard")
        if node.children:
            self.problem(node, label, "a SubTree has no child nodes")
        if tree_id not in self.doc.trees:
            self.problem(node, f"SubTree '{tree_id}'", "no <BehaviorTree> with this ID in "
                         f"the file (trees: {', '.join(self.doc.trees)})")
            return []
        if len(path) >= MAX_DEPTH // 8:
            self.problem(node, f"SubTree '{tree_id}'", f"subtrees nested deeper than "
                         f"{MAX_DEPTH // 8}")
            return []
        if tree_id in path:
            cycle = " -> ".join((*path[path.index(tree_id):], tree_id))
            self.problem(node, f"SubTree '{tree_id}'", f"cycle of subtrees: {cycle}")
            return []
        inner = self.tree(tree_id, (*path, tree_id))
        if not inner:
            return []
        name = node.attrib.get("name", tree_id)
        if self.context is None:
            return [_Checked(name)]
        built = REGISTRY["SubTree"].build(self.context, name, {}, inner)
        built.bt_id = "SubTree"
        built.bt_subtree = tree_id
        built.bt_ports = {}
        return [built]

    def tree(self, tree_id: str, path: tuple[str, ...]) -> list[py_trees.behaviour.Behaviour]:
        return self.node(self.doc.trees[tree_id].children[0], self.settings, path)


@dataclass
class _Checked:
    """Stands for a node that was checked but not built."""

    name: str


def _waypoint_hint(name: str, settings: dict[str, Any]) -> str:
    if re.fullmatch(r"waypoint_\d+", name):
        return f" (it has {settings['waypoint_count']} waypoints)"
    if name in ("waypoint", "waypoint_number"):
        return " (only inside MissionWaypoints)"
    return ""


def _substitute(name: str, settings: dict[str, Any]) -> str:
    """``{setting}`` in a node name replaced by the setting's value."""
    return re.sub(r"\{(\w+)\}", lambda m: format_value(settings[m.group(1)])
                  if m.group(1) in settings else m.group(0), name)


def check_tree(document: TreeDocument, settings: dict[str, Any],
               services: frozenset[str] | set[str] = frozenset()) -> list[str]:
    """Every problem of ``document`` flown with the mission ``settings``
    (:func:`behaviors.registry.mission_settings`) and ``services`` (names of
    :data:`behaviors.registry.SERVICES` the mission provides), one line each; [] when it is
    fine."""
    checker = _Builder(document, settings, None, frozenset(services))
    checker.tree(document.main, (document.main,))
    return list(dict.fromkeys(checker.problems))


def build_tree(document: TreeDocument, settings: dict[str, Any], context: BuildContext
               ) -> tuple[py_trees.behaviour.Behaviour, list[str]]:
    """The root of the built main tree and the blackboard keys its ports name.

    Resets the mission's blackboard keys to their start values (and the tree's own
    entries to None) as it builds.

    Raises:
        TreeFileError: the problems :func:`check_tree` reports (checked as it builds).
    """
    keys.reset()
    keys.initialise()
    builder = _Builder(document, settings, context)
    built = builder.tree(document.main, (document.main,))
    if builder.problems:
        raise TreeFileError(list(dict.fromkeys(builder.problems)))
    root = built[0]
    root.bt_tree = document.main
    return root, [k for k in builder.runtime_keys if k not in keys.DEFAULTS]
