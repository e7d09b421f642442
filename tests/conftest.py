"""Shared pytest configuration."""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

_ROOT = Path(__file__).resolve().parents[1]
_DEMO = _ROOT / "missions" / "mars_demo.yaml"


def pytest_configure(config) -> None:
    """Under pytest-xdist, fly the demo once in the controller before the workers start.

    In a fresh checkout numba compiles the perception kernels on first use (about a minute
    of CPU) and caches them beside their modules. Without this, every worker compiles the
    same kernels at once inside whichever test first flies, which on a busy two-core
    machine pushed such a test past its timeout; flown here, the workers load the cache.
    Skipped once the render's and the map's kernels are cached (numba's index files);
    the outcome is not checked: the tests fly the demo themselves.
    """
    distributed = (config.pluginmanager.hasplugin("xdist")
                   and config.getoption("numprocesses", None))
    if not distributed or hasattr(config, "workerinput"):
        return
    if all(any((_ROOT / package).glob("**/__pycache__/*.nbi")) for package in ("sitl", "lsd")):
        return
    with tempfile.TemporaryDirectory(prefix="lander-warm-") as out:
        subprocess.run([sys.executable, "-m", "autonomy", "fly", str(_DEMO),
                        "--out", out, "--quiet"], capture_output=True, check=False)
