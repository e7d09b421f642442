"""Link health on a live flight: a dead autopilot is reported at once and ends the flight as
link_lost; a short outage is ridden out; nothing listening gives up after the connect
timeout."""

from __future__ import annotations

import json
import socket
import threading
from pathlib import Path

from autonomy.cli import main
from autonomy.config import apply_overrides, load_mission
from autonomy.report import read_events
from autonomy.runner import REPORT_FILES, fly

DEMO = Path(__file__).resolve().parents[2] / "missions" / "demo.yaml"


def short_mission(url: str, **overrides):
    """One waypoint 20 m east, a site beside it: a landing about 40 simulated s long."""
    return apply_overrides(load_mission(DEMO), {
        "vehicle.connection": url,
        "waypoints": [[20.0, 0.0, 12.0]],
        "cruise_altitude": 12.0,
        "sites": [{"x": 22.0, "y": 4.0, "size": 5.0}],
        **overrides,
    })


def when_airborne(sitl, action) -> threading.Thread:
    """Run ``action()`` once the simulated vehicle has climbed 5 m."""

    def watch():
        while sitl.truth.position[2] < 5.0:
            threading.Event().wait(0.005)
        action()

    thread = threading.Thread(target=watch, daemon=True)
    thread.start()
    return thread


def link_events(events):
    return [e for e in events if e["kind"] == "link"]


def test_a_killed_autopilot_is_reported_at_once_and_ends_as_link_lost(
        served_sitl, tmp_path, capsys):
    served = served_sitl(speedup=10.0)
    mission = short_mission(served.url, **{"vehicle.link.loss_wait": 10.0})
    killer = when_airborne(served.sitl, served.kill)
    result = fly(mission, out_dir=tmp_path, console=True)
    killer.join(timeout=5)

    summary = result.summary
    assert (summary["outcome"], summary["exit_code"]) == ("link_lost", 4)
    assert summary["link_lost"].startswith("link lost for 10.")
    assert summary["link_lost"].endswith("(vehicle.link.loss_wait 10 s)")
    link = summary["link"]
    assert link["losses"] == 1 and link["time_lost"] >= 10.0
    assert link["longest_heartbeat_gap"] >= link["time_lost"]
    # Declared lost once the autopilot had been silent for the link timeout (3 s), then
    # given up after the wait, with no landing attempted over the dead link.
    on_disk = read_events(tmp_path / "events.jsonl")
    lost, gave_up = link_events(on_disk)
    assert lost["event"] == "lost" and 3.0 <= lost["silent_for"] < 4.0
    assert gave_up["event"] == "gave_up" and gave_up["t"] > lost["t"]
    assert not [e for e in on_disk if e["kind"] == "flight" and e.get("event") == "land"]
    out = capsys.readouterr().out
    assert out.index("LINK LOST: no heartbeat for 3.") < out.index("giving up: link lost")
    assert "outcome: link_lost" in out and "exit 4: link lost" in out


def test_a_short_outage_is_ridden_out_and_the_flight_lands(served_sitl, tmp_path):
    served = served_sitl(speedup=10.0)
    mission = short_mission(served.url)

    def outage():
        served.pause()  # about 10 s of the vehicle's time at 10x
        threading.Event().wait(1.0)
        served.resume()

    pauser = when_airborne(served.sitl, outage)
    result = fly(mission, out_dir=tmp_path)
    pauser.join(timeout=5)

    summary = result.summary
    assert (summary["outcome"], summary["exit_code"]) == ("landed_unjudged", 3)
    assert summary["link"]["losses"] == 1
    events = link_events(result.events)
    assert [e["event"] for e in events] == ["lost", "regained", "resume"]
    assert events[2]["behaviour"] in ("Takeoff", "Waypoint 1")  # restarted, not failed
    assert served.sitl.truth.landed and not served.sitl.truth.armed


def test_nothing_listening_gives_up_after_the_connect_timeout(tmp_path, capsys):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    url = f"udpin:127.0.0.1:{port}"
    code = main(["fly", str(DEMO), "--connect", url, "--set", "vehicle.link.connect_timeout=1",
                 "--out", str(tmp_path)])
    assert code == 4
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].endswith(f"waiting for a heartbeat on {url} (up to 1 s)")
    assert lines[1].endswith(f"no heartbeat on {url} within 1 s (is the autopilot running, "
                             "and is the URL right?)")
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["outcome"] == "link_lost" and summary["link"]["heartbeats"] == 0
    assert all((tmp_path / name).is_file() for name in REPORT_FILES)
