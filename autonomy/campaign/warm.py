"""Warm campaign workers: what a local pool's fork server imports before it forks them.

A worker forked from the server starts with everything the server imported, so the flight
stack (about 3 s of CPU to import), the world generator and perception source the
campaign's missions use, and their compiled kernels loaded from numba's on-disk cache (about
0.6 s more at a process's first compiled call) are paid once per campaign instead of once
per worker. Loading only reads the cache: a kernel not yet cached, or cached for another
machine or an older source, is left to compile on first use as before.
"""

from __future__ import annotations

import sys
from collections.abc import Iterable
from typing import Any

# Modules whose compiled kernels the server loads.
_PACKAGES = ("autonomy.", "sitl.", "lsd.", "lsm.", "behaviors.")
# The site source of each detector (built by autonomy.runner.world.build_source).
_SOURCES = {
    "elevation_map": "autonomy.perception.elevation",
    "depth_costmap": "autonomy.perception.costmap",
    "lidar_pca": "autonomy.perception.lidar",
}
# Imported last by the fork server: loads the kernels of everything imported before it.
KERNELS_MODULE = "autonomy.campaign._load_kernels"


def preload_modules(missions: Iterable[Any]) -> list[str]:
    """Modules a fork server imports for flights of ``missions`` (lander missions), in
    order, ending with :data:`KERNELS_MODULE`."""
    from sitl.terrain.worlds import generator_module

    modules = ["autonomy.runner"]
    for mission in missions:
        world = getattr(mission, "world", None)
        perception = getattr(mission, "perception", None)
        found = [generator_module(world.kind) if world is not None else None,
                 _SOURCES.get(getattr(perception, "detector", None))]
        modules += [m for m in found if m and m not in modules]
    return modules + [KERNELS_MODULE]


def load_cached_kernels() -> int:
    """Load every cached compiled kernel of the project's imported modules; returns how
    many signatures were loaded. Never raises (the fork server must start whatever
    happens here)."""
    if "numba" not in sys.modules:
        return 0
    try:
        from numba.core.registry import CPUDispatcher
    except Exception:  # pragma: no cover - another numba layout: workers load on first use
        return 0
    loaded = 0
    for name, module in list(sys.modules.items()):
        if module is None or not name.startswith(_PACKAGES):
            continue
        for value in list(vars(module).values()):
            if isinstance(value, CPUDispatcher):
                loaded += _load(value)
    return loaded


def _load(dispatcher: Any) -> int:
    """Load ``dispatcher``'s signatures that its cache holds for this machine and source."""
    loaded = 0
    try:
        cache = dispatcher._cache
        index = cache._cache_file._load_index()
        codegen = dispatcher.targetctx.codegen()
        for key in index:
            signature = key[0]
            # only exact hits: a stale or foreign entry would be compiled here instead
            if key == cache._index_key(signature, codegen):
                dispatcher.compile(signature)
                loaded += 1
    except Exception:  # NullCache (no cache=True), an unreadable index: load on first use
        pass
    return loaded
