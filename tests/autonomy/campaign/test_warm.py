"""A local pool's fork server preloads the flight stack and its compiled kernels, so the
workers it forks start warm (autonomy.campaign.warm)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[3]

# Run as a fresh interpreter (the fork server is one per process): make sure the terraces'
# kernel is in numba's disk cache, start a fork server with the Mars mission's preload and
# ask a forked worker what it started with.
PROBE = """
import json, multiprocessing, sys
from concurrent.futures import ProcessPoolExecutor


def started_with():
    from sitl.terrain import terrace_kernel
    return {"stack": "autonomy.runner" in sys.modules,
            "source": "autonomy.perception.elevation" in sys.modules,
            "kernel signatures": len(terrace_kernel._add_bracketed.signatures)}


if __name__ == "__main__":
    import numpy as np
    from autonomy.campaign.warm import preload_modules
    from autonomy.config import load_mission
    from sitl.terrain.terrace_kernel import add_terrace

    xs = np.arange(5.0)
    add_terrace(np.zeros((5, 5), np.float32), xs, xs, 2.0, 2.0, 0.3, 1.0, 3.0, 2.0, 4.0, 1.0)
    mission = load_mission(sys.argv[1])
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(["__main__"] + (preload_modules([mission]) if sys.argv[2]
                                                   == "warm" else []))
    with ProcessPoolExecutor(1, mp_context=context) as pool:
        print(json.dumps(pool.submit(started_with).result()))
"""


def _worker_start(tmp_path, mode):
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    out = subprocess.run([sys.executable, str(script), "missions/mars_science.yaml", mode],
                         cwd=ROOT, check=True, capture_output=True, text=True).stdout
    return json.loads(out.splitlines()[-1])


def test_workers_of_a_warm_fork_server_start_with_the_stack_and_loaded_kernels(tmp_path):
    warm = _worker_start(tmp_path, "warm")
    assert warm["stack"] and warm["source"] and warm["kernel signatures"] >= 1
    # without the preload a worker starts with neither
    assert _worker_start(tmp_path, "cold") == {"stack": False, "source": False,
                                                "kernel signatures": 0}
