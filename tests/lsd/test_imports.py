"""Every module of the perception packages imports on its own, as a user's script's first
import would (a circular import shows only when the cycle is entered from its far side)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

# Imports each module of lsm and lsd as the first of its packages: the packages' modules are
# dropped from sys.modules before each one, the third-party ones stay loaded (cheap).
_SCRIPT = """
import importlib, pkgutil, sys
packages = ("lsm", "lsd")
names = []
for package in packages:
    names.append(package)
    path = importlib.import_module(package).__path__
    names += [m.name for m in pkgutil.walk_packages(path, package + ".")]
for name in names:
    for loaded in [m for m in sys.modules if m.split(".")[0] in packages]:
        del sys.modules[loaded]
    try:
        importlib.import_module(name)
    except ImportError as exc:
        print(f"{name}: {exc}")
print(f"{len(names)} modules")
"""


def test_each_perception_module_imports_first():
    out = subprocess.run([sys.executable, "-c", _SCRIPT], cwd=ROOT, capture_output=True,
                         text=True, check=True).stdout.splitlines()
    assert out[-1].endswith(" modules") and int(out[-1].split()[0]) > 20, out
    assert out[:-1] == []
