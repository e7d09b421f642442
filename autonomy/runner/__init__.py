"""The mission runner: flies a :class:`~autonomy.config.Mission` and writes its report.

    from autonomy.config import load_mission
    from autonomy.runner import fly
    result = fly(load_mission("missions/demo.yaml"), seed=3, out_dir="out/demo")
    result.summary["outcome"]  # one of autonomy.report.OUTCOMES; result.exit_code as lander fly
"""

from autonomy.runner.flight import Flight, PhaseConsole
from autonomy.runner.home import HomeMismatch
from autonomy.runner.run import REPORT_FILES, FlightResult, fly
from autonomy.runner.world import FlightSeeds

__all__ = [
    "REPORT_FILES",
    "Flight",
    "FlightResult",
    "FlightSeeds",
    "HomeMismatch",
    "PhaseConsole",
    "fly",
]
