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


# The modules whose tests take tens of seconds each (flights, fuzzing, a whole real model),
# longest first. pytest-xdist's default (load) scheduling hands tests out in collection
# order as workers free up; run last, one of these keeps a worker busy for a minute while
# the other has nothing left to do. Run first, the many short tests fill in behind them.
_LONG_FIRST = (
    "tests/fuzz/test_fuzz.py",
    "tests/e2e/test_sitl_fuzz.py",
    "tests/e2e/test_demo_flight.py",
    "tests/e2e/test_detectors_fly.py",
    "tests/autonomy/campaign/test_warm.py",
    "tests/autonomy/test_approach_flight.py",
    "tests/speed/test_outcome_equality.py",
    "tests/lsm/test_reference_model.py",
    "tests/conformance/test_mavsdk_common.py",
    "tests/sitl/test_geotiff.py",
)


def pytest_collection_modifyitems(config, items) -> None:
    """Move the long modules' tests to the front, each module's tests kept together and in
    their order (module fixtures are built once); every worker collects the same order."""
    rank = {module: place for place, module in enumerate(_LONG_FIRST)}

    def place(item) -> int:
        module = item.path.relative_to(_ROOT).as_posix()
        return rank.get(module, len(_LONG_FIRST))

    items.sort(key=place)  # stable: the rest keep their collection order
