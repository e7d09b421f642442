"""The mission runner: flies a :class:`~autonomy.config.Mission` and writes its report.

    from autonomy.config import load_mission
    from autonomy.runner import fly
    result = fly(load_mission("missions/demo.yaml"), seed=3, out_dir="out/demo")
    result.summary["outcome"]  # landed, landed_unsafe, crashed, no_site, failsafe, aborted
"""

from autonomy.runner.flight import Flight, PhaseConsole
from autonomy.runner.run import REPORT_FILES, FlightResult, fly
from autonomy.runner.world import FlightSeeds

__all__ = ["REPORT_FILES", "Flight", "FlightResult", "FlightSeeds", "PhaseConsole", "fly"]
