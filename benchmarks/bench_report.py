"""What a flight's report costs: writing report.html (and report.png beside it) for one
flight, against the flight itself, and the telemetry a log viewer needs in flight.tlog.

    python benchmarks/bench_report.py

Flies missions/demo.yaml once in lockstep, then times each report writer over a few repeats
(median), and prints the times and the sizes of the files. A campaign of N flights writes N
pages: N times the figure printed here.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from _checkout import ROOT  # noqa: E402  (this checkout's packages first)

from autonomy.config import load_mission  # noqa: E402
from autonomy.report import write_flight_page, write_report_png  # noqa: E402
from autonomy.runner import fly  # noqa: E402
from autonomy.vehicle.settings import LOG_STREAMS  # noqa: E402

REPEATS = 5


def median_time(fn) -> float:
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    mission = load_mission(ROOT / "missions" / "demo.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        start = time.perf_counter()
        bare = fly(mission, out_dir=None)
        flight_bare = time.perf_counter() - start
        start = time.perf_counter()
        result = fly(mission, out_dir=out)
        flight_files = time.perf_counter() - start
        html = median_time(lambda: write_flight_page(result.data, result.summary, result.events,
                                                     out))
        png = median_time(lambda: write_report_png(result.data, out / "report.png",
                                                   outcome=result.outcome))
        sizes = {p.name: p.stat().st_size for p in sorted(out.iterdir())}
    # The log viewers' streams (GLOBAL_POSITION_INT, VFR_HUD, asked for when a tlog is
    # written): flights writing their files with them, and with them switched off.
    link = mission.vehicle.link
    streams = {**link.streams, **dict.fromkeys(LOG_STREAMS, 0.0)}
    lean = mission.model_copy(update={"vehicle": mission.vehicle.model_copy(
        update={"link": link.model_copy(update={"streams": streams})})})
    with_streams, without = [], []
    for _ in range(3):  # interleaved, so that the machine's load weighs on both alike
        for target, m in ((with_streams, mission), (without, lean)):
            with tempfile.TemporaryDirectory() as tmp:
                start = time.perf_counter()
                fly(m, out_dir=tmp, report_png=False)
                target.append(time.perf_counter() - start)
    assert bare.outcome == result.outcome  # writing the report changes nothing of the flight
    print(f"demo flight ({result.summary['mission_time']:.0f} s simulated): "
          f"{flight_bare:.2f} s wall without report files, {flight_files:.2f} s with them")
    print(f"report.html: {html * 1000:.0f} ms to write (median of {REPEATS}), "
          f"{sizes['report.html'] / 1024:.0f} KiB")
    print(f"report.png:  {png * 1000:.0f} ms to write (median of {REPEATS}), "
          f"{sizes['report.png'] / 1024:.0f} KiB")
    print(f"report.html / flight without files: {html / flight_bare:.2f}; "
          f"200 pages: {200 * html:.0f} s of worker time")
    print("files: " + ", ".join(f"{k} {v / 1024:.0f} KiB" for k, v in sizes.items()))
    a, b = statistics.median(with_streams), statistics.median(without)
    print(f"flight writing its report folder with the log viewers' streams {a:.2f} s, with "
          f"them off {b:.2f} s (median of 3): ratio {a / b:.2f}")


if __name__ == "__main__":
    main()
