"""flight.tlog as log viewers read it: pymavlink's own mavlogdump.py draws the track."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pymavlink
import pytest

from autonomy.cli.demo import mission_path
from autonomy.config import load_mission

MAVLOGDUMP = Path(pymavlink.__file__).parent / "tools" / "mavlogdump.py"
EARTH_RADIUS = 6_378_137.0


def test_mavlogdump_reads_the_track_and_the_hud_at_ground_station_rates(demo_flight):
    mission = load_mission(mission_path("demo.yaml"))
    dump = subprocess.run(
        [sys.executable, str(MAVLOGDUMP), "--format", "json", "--source-system", "1", "--types",
         "GLOBAL_POSITION_INT,ATTITUDE,HEARTBEAT,VFR_HUD", str(demo_flight.out_dir /
                                                              "flight.tlog")],
        capture_output=True, text=True, check=True, timeout=120,
    )
    messages = [json.loads(line) for line in dump.stdout.splitlines() if line.startswith("{")]
    vehicle = messages  # what the vehicle sent (system 1), not the ground station's own
    counts = Counter(m["meta"]["type"] for m in vehicle)
    duration = demo_flight.summary["mission_time"]
    assert counts["GLOBAL_POSITION_INT"] == pytest.approx(5 * duration, rel=0.1)
    assert counts["VFR_HUD"] == pytest.approx(4 * duration, rel=0.1)
    assert counts["ATTITUDE"] == pytest.approx(10 * duration, rel=0.1)
    assert counts["HEARTBEAT"] == pytest.approx(duration, rel=0.1)
    # Timestamps run with the simulated flight (lockstep), as a viewer's time axis shows it.
    stamps = [m["meta"]["timestamp"] for m in vehicle]
    assert stamps == sorted(stamps)
    assert stamps[-1] - stamps[0] == pytest.approx(duration, abs=1.5)

    # The track: lat/lon about home in metres (flat earth, fine over a few hundred metres).
    home = mission.home
    track = [(m["data"]["lat"] / 1e7, m["data"]["lon"] / 1e7, m["data"]["relative_alt"] / 1e3)
             for m in vehicle if m["meta"]["type"] == "GLOBAL_POSITION_INT"]
    north = [math.radians(lat - home.lat) * EARTH_RADIUS for lat, _, _ in track]
    east = [math.radians(lon - home.lon) * EARTH_RADIUS * math.cos(math.radians(home.lat))
            for _, lon, _ in track]
    touchdown = demo_flight.summary["touchdown"]
    assert math.hypot(east[-1] - touchdown["x"], north[-1] - touchdown["y"]) < 1.0
    for x, y, _ in mission.waypoints_enu():  # the survey shows on the map: each one reached
        nearest = min(math.hypot(e - x, n - y) for e, n in zip(east, north, strict=True))
        assert nearest < 3.0, (x, y)
    assert max(alt for _, _, alt in track) == pytest.approx(
        max(p[2] for p in demo_flight.data.trace.xyz), abs=0.5)
    hud = [m["data"] for m in vehicle if m["meta"]["type"] == "VFR_HUD"]
    assert max(h["alt"] for h in hud) == pytest.approx(home.alt + max(a for _, _, a in track),
                                                       abs=0.5)
    assert max(h["groundspeed"] for h in hud) > 2.0
