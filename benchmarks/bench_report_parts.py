"""What each writer of a campaign run's report directory costs, on one real flight.

Flies the mission once as a campaign run does (report directory, no report.png), then times
each writer again on that flight's data, in this process's CPU time, best of a few repeats:
the map of report.html (hill shading, then the image with its PNG), the whole page
(``build_page``, then its HTML), and the event log writing the flight's events to
events.jsonl (cleaning, JSON, the line-buffered file). The tree logs' cost per tick is
benchmarks/bench_tick_log.py's.

    python benchmarks/bench_report_parts.py [--mission missions/mars_science.yaml]
        [--seed 3757552657]

To compare with an older checkout, run this script with ``PYTHONPATH=<that checkout>``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from _checkout import ROOT  # noqa: E402  (this checkout's packages first)

from autonomy.campaign.worker import fly_with_page  # noqa: E402
from autonomy.config import load_mission  # noqa: E402
from autonomy.report import events as event_log  # noqa: E402
from autonomy.report import html, page, plot  # noqa: E402

REPEATS = 5


def best_ms(fn) -> float:
    """The fastest of REPEATS calls, in ms of this process's CPU time."""
    times = []
    for _ in range(REPEATS):
        start = time.process_time()
        fn()
        times.append(time.process_time() - start)
    return min(times) * 1e3


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mission", default=str(ROOT / "missions" / "mars_science.yaml"))
    parser.add_argument("--seed", type=int, default=3757552657)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        result = fly_with_page(load_mission(args.mission), args.seed, out)
        data, summary, events = result.data, result.summary, result.events
        window = plot.map_window(data, data.trace.arrays()[1])
        built = page.build_page(data, summary, events, out)
        fields = [{k: v for k, v in e.items() if k not in ("t", "kind")} for e in events]

        def write_events() -> None:
            log = event_log.EventLog(lambda: 0.0, out / "events-again.jsonl")
            for event, extra in zip(events, fields, strict=True):
                log.add(event["kind"], **extra)
            log.close()

        parts = {
            "map: hill shading": lambda: plot.shaded_terrain(data.terrain, window,
                                                             page.MAP_PIXELS),
            "map: shading + PNG": lambda: page._map_image(data, window),
            "page: build_page": lambda: page.build_page(data, summary, events, out),
            "page: its HTML": lambda: html.render_html(built),
            f"events.jsonl: {len(events)} events": write_events,
        }
        print(f"== {Path(args.mission).name} seed {args.seed}: "
              f"{summary['mission_time']:.0f} s simulated, outcome {summary['outcome']} ==")
        for name, fn in parts.items():
            print(f"  {name:34s} {best_ms(fn):7.1f} ms CPU (best of {REPEATS})")


if __name__ == "__main__":
    main()
