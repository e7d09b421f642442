"""py_trees behaviours of the landing mission and the tree builder.

Behaviours reach the vehicle only through the ports declared in :mod:`behaviors.ports`
and read time only from the injected clock; this package never imports :mod:`autonomy`.

Entry points: :func:`behaviors.tree.build_mission_tree` (a :class:`MissionPlan` and a
BehaviorTree.CPP v4 XML tree file -> the tree; the built-in one is ``landing_tree.xml``),
the node registry in :mod:`behaviors.registry`, the tree file loader in
:mod:`behaviors.loader`, the tick log in :mod:`behaviors.btlog` (Groot2's ``.btlog``), the
blackboard keys in :mod:`behaviors.blackboard`, and :func:`render_ascii` / :func:`write_dot`
to look at a tree.
"""

from behaviors.display import render_ascii, write_dot
from behaviors.settings import LandingSettings, MissionPlan
from behaviors.tree import build_mission_tree

__all__ = ["LandingSettings", "MissionPlan", "build_mission_tree", "render_ascii", "write_dot"]
