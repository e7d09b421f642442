"""Imported first by the benchmark scripts: this checkout's root goes first on ``sys.path``.

Run as ``python benchmarks/NAME.py``, a script's own folder leads ``sys.path``, so the
project's packages would come from wherever the environment's editable install points,
perhaps another checkout: a benchmark measures the code beside it. A PYTHONPATH set by the
caller wins (``--before`` runs a script of this checkout on an older checkout's packages).
"""

import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if not os.environ.get("PYTHONPATH") and sys.path[:1] != [str(ROOT)]:
    sys.path.insert(0, str(ROOT))
