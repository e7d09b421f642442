"""Makes the behaviour-test doubles importable as ``behaviors_fakes`` and the pre-XML tree
builder as ``behaviors_legacy_tree`` however pytest is run (the suite uses
--import-mode=importlib, which puts no test directory on sys.path)."""

import importlib.util
import sys
from pathlib import Path

import py_trees
import pytest

for _name, _file in (("behaviors_fakes", "fakes.py"), ("behaviors_legacy_tree", "legacy_tree.py")):
    if _name not in sys.modules:
        _spec = importlib.util.spec_from_file_location(_name, Path(__file__).with_name(_file))
        _module = importlib.util.module_from_spec(_spec)
        sys.modules[_name] = _module
        _spec.loader.exec_module(_module)


@pytest.fixture(autouse=True)
def _clean_blackboard():
    """Every test starts and ends with an empty py_trees blackboard (it is global)."""
    py_trees.blackboard.Blackboard.clear()
    yield
    py_trees.blackboard.Blackboard.clear()
