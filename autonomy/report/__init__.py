"""The flight report: summary.json, events.jsonl, flight.tlog, report.png and report.html.

The runner fills a :class:`FlightData` while it flies and records events in an
:class:`EventLog`; :func:`build_summary` turns the data into the summary.json dict and
:func:`write_report_png` draws the map and altitude plot; :func:`write_flight_page` writes
report.html, the flight to inspect in a browser.
"""

from autonomy.report.data import FlightData, FlightTrace
from autonomy.report.events import EventLog, TreeStatusRecorder, read_events
from autonomy.report.html import REPORT_HTML, write_flight_page
from autonomy.report.plot import write_report_png
from autonomy.report.summary import (
    EXIT_CODES,
    EXIT_MEANINGS,
    OUTCOMES,
    build_summary,
    classify,
    exit_code,
    format_summary,
    write_summary,
)

__all__ = [
    "EXIT_CODES",
    "EXIT_MEANINGS",
    "OUTCOMES",
    "REPORT_HTML",
    "EventLog",
    "FlightData",
    "FlightTrace",
    "TreeStatusRecorder",
    "build_summary",
    "classify",
    "exit_code",
    "format_summary",
    "read_events",
    "write_flight_page",
    "write_report_png",
    "write_summary",
]
