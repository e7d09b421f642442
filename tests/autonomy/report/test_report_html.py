"""report.html of a real flight: what it holds, and how it behaves in headless Chromium."""

from __future__ import annotations

import json
import re
import shutil

import numpy as np
import pytest

from autonomy.report import write_flight_page
from autonomy.report.page import build_page, loss_terms


def embedded(path):
    """The flight data a report.html embeds."""
    return embedded_text(path.read_text(encoding="utf-8"))


def test_loss_terms_add_up_to_the_loss_the_lsm_ranked_by(demo_flight):
    data = demo_flight.data
    assert len(data.sites) >= 2
    props = np.array([[s.x, s.y, s.roughness, s.uncertainty, s.size, s.verification_altitude]
                      for s in data.sites])
    end_xy = data.trace.xyz[-1][:2]
    terms = loss_terms(props, end_xy, data.weights)
    assert terms.shape == (len(data.sites), 5)
    np.testing.assert_allclose(terms.sum(axis=1), [s.loss for s in data.sites], atol=1e-6)
    assert (terms[:, 3] <= 0).all()  # the size term is a bonus


def test_the_page_holds_every_site_ban_phase_and_event_of_the_flight(demo_flight):
    page = embedded(demo_flight.out_dir / "report.html")
    data, summary = demo_flight.data, demo_flight.summary
    assert page["summary"]["outcome"] == summary["outcome"] == "landed"
    assert {s["id"] for s in page["sites"]} == {s.id for s in data.sites}
    assert sum(s["verified"] for s in page["sites"]) == summary["sites_verified"] == 1
    assert page["chosen"] == data.chosen_site.id
    assert len(page["bans"]) == summary["sites_banned"] == 1
    assert page["bans"][0]["t"] is not None  # when it was banned, from the LSM's events
    assert [p for _, p in page["phases"]] == [p for _, p in data.trace.phases]
    lsm_events = [e for e in demo_flight.events if e["kind"] == "lsm"]
    assert len([e for e in page["events"] if e[1] == "lsm"]) == len(lsm_events)
    # The tree's timeline from the events: every node that changed status has a lane.
    paths = {e["path"] for e in demo_flight.events if e["kind"] == "tree"}
    assert paths <= {lane["path"] for lane in page["tree"]["lanes"]}
    assert page["map"] is not None and page["map"]["href"].startswith("data:image/png;base64,")
    assert page["end"] == pytest.approx(summary["mission_time"])


def test_the_tree_timeline_comes_from_the_flights_btlog_and_matches_its_events(
        demo_flight, tmp_path):
    page = embedded(demo_flight.out_dir / "report.html")
    assert page["tree"]["source"] == "tree.btlog" and not page["tree"]["truncated"]
    from_events = build_page(demo_flight.data, demo_flight.summary, demo_flight.events)
    assert from_events["tree"]["source"] == "events.jsonl"
    # The same bars whichever log they came from: both saw every status change.
    def bars(tree):
        return sorted([tree["lanes"][int(lane)]["path"], t0, t1, code]
                      for lane, t0, t1, code in tree["segments"])
    assert bars(page["tree"]) == bars(from_events["tree"])
    assert len(page["tree"]["lanes"]) >= len(from_events["tree"]["lanes"])  # all nodes

    # An interrupted flight's log, cut inside its last record: shown to the one before.
    out = tmp_path / "flight"
    shutil.copytree(demo_flight.out_dir, out)
    whole = (out / "tree.btlog").read_bytes()
    (out / "tree.btlog").write_bytes(whole[:-5])
    write_flight_page(demo_flight.data, demo_flight.summary, demo_flight.events, out)
    cut = embedded(out / "report.html")
    assert cut["tree"]["truncated"]
    assert len(cut["tree"]["segments"]) in (len(page["tree"]["segments"]) - 1,
                                            len(page["tree"]["segments"]))
    assert bars(cut["tree"]) != bars(page["tree"])


def test_report_html_loads_in_chromium_without_errors_and_shows_the_loss_terms(
        demo_flight, chromium):
    page = demo_flight.out_dir / "report.html"
    chosen = demo_flight.data.chosen_site
    takeoff = next(t for t, p in demo_flight.data.trace.phases if p == "mission")
    report = chromium.inspect(page.resolve().as_uri(), [
        ("eval", "document.body.getAttribute('data-ready')"),
        ("hover", "#map .site"),
        ("eval", "document.getElementById('tip').innerText"),
        ("eval", f"(function(){{var s=document.getElementById('slider');s.value={takeoff + 1};"
                 "s.dispatchEvent(new Event('input'));"
                 "return document.getElementById('readout').innerText;})()"),
        ("eval", "document.querySelectorAll('#tree rect').length"),
        ("eval", "document.querySelectorAll('#map .site.future').length"),
    ])
    shot = demo_flight.out_dir / "report-screenshot.png"
    shot.write_bytes(report.screenshot)
    assert report.exceptions == [] and report.console_errors == []
    # One file: nothing fetched but the page itself and its inline images.
    assert [u for u in report.requests if not u.startswith(("file:", "data:"))] == []
    ready, _, tip, readout, bars, future = report.results
    assert ready == "1"
    assert tip.startswith("site ")
    for term in ("w_dist", "w_rough", "w_var", "w_size", "w_verAlt"):
        assert term in tip
    shown = re.search(r"\nL\s+(-?\d+\.\d+)", tip)
    terms = [float(v) for v in re.findall(r"(-?\d+\.\d{3})\n", tip)[:5]]
    assert shown and float(shown.group(1)) == pytest.approx(sum(terms), abs=2e-3)
    assert "phase mission" in readout  # the slider moved the whole page to that time
    assert bars > 10
    assert future >= 1  # sites not yet found at that time are faded
    assert chosen is not None
    # A real picture: a PNG of the viewport with more than a few colours in it.
    import cv2

    image = cv2.imdecode(np.frombuffer(report.screenshot, np.uint8), cv2.IMREAD_COLOR)
    assert image.shape[:2] == (1300, 1600)
    colours = image.reshape(-1, 3).astype(np.int64) @ np.array([1 << 16, 1 << 8, 1])
    assert len(np.unique(colours)) > 50


def test_text_in_the_data_cannot_end_the_pages_script():
    from autonomy.report.html import render_html

    page = {"summary": {"mission": "a</script><!--<b>", "seed": 1}}
    text = render_html(page)
    assert text.count("</script>") == 2  # the data's and the viewer's, none from the data
    assert embedded_text(text) == page


def embedded_text(text):
    match = re.search(r'<script id="flight-data" type="application/json">(.*?)</script>',
                      text, re.S)
    return json.loads(match.group(1))


@pytest.fixture(scope="module")
def car_flight(tmp_path_factory):
    """A short flight over a flat world where a car drives a lane past the site."""
    from autonomy.config import Mission
    from autonomy.runner import fly

    mission = Mission.model_validate({
        "name": "car past the site", "cruise_altitude": 15.0,
        "waypoints": [[10.0, 0.0, 15.0]], "landing": {"verify": False},
        "world": {"kind": "flat", "size": [60.0, 60.0], "cell_size": 0.5,
                  "moving_obstacles": {"paths": [
                      {"kind": "vehicle", "path": [[18.0, -20.0], [18.0, 20.0]], "speed": 3.0},
                      {"kind": "person", "path": [[5.0, 5.0], [9.0, 9.0], [5.0, 9.0]],
                       "speed": 1.0, "closed": True}]}},
        "sitl": {"wind": {"speed": 0.0}},
        "perception": {"detector": "scripted", "rate": 2.0},
        "sites": [{"x": 12.0, "y": 0.0, "size": 4.0}], "seed": 1, "time_limit": 120.0,
    })
    out = tmp_path_factory.mktemp("car-report")
    return fly(mission, out_dir=out)


def test_the_page_draws_moving_obstacles_their_paths_and_where_they_were_at_touchdown(
        car_flight, chromium):
    path = car_flight.out_dir / "report.html"
    moving = embedded(path)["moving"]
    world = car_flight.data.terrain.moving
    assert moving["kind"] == ["vehicle", "person"]
    assert moving["path"][0] == [[18.0, -20.0], [18.0, 20.0]]
    assert moving["path"][1][0] == moving["path"][1][-1]  # the closed walk drawn round
    touchdown = car_flight.summary["touchdown"]
    at = world.at(touchdown["t"])
    assert moving["touchdown"]["y"][0] == pytest.approx(at.y[0], abs=1e-3)
    middle = len(moving["t"]) // 2
    assert moving["y"][middle][0] == pytest.approx(world.at(moving["t"][middle]).y[0], abs=0.01)
    report = chromium.inspect(path.resolve().as_uri(), [
        ("eval", "document.body.getAttribute('data-ready')"),
        ("eval", "Array.from(document.querySelectorAll('#map title')).map("
                 "function (t) { return t.textContent; }).join('|')"),
        ("eval", "(function(){var s=document.getElementById('slider');s.value=3;"
                 "s.dispatchEvent(new Event('input'));return Array.from("
                 "document.querySelectorAll('#map title')).filter(function (t) {"
                 "return / at \\d/.test(t.textContent) && !/touchdown/.test(t.textContent);})"
                 ".map(function (t) { return t.textContent; }).join('|');})()"),
    ])
    assert report.exceptions == [] and report.console_errors == []
    ready, titles, live = report.results
    assert ready == "1"
    for text in ("vehicle 0 path", "person 1 path", "vehicle 0 at touchdown",
                 "person 1 at touchdown"):
        assert text in titles
    shown = _at(moving, 3.0)
    assert live == f"vehicle 0 at {shown} s|person 1 at {shown} s"  # placed at the slider's


def _at(moving, t):
    """The page's placing time for slider time ``t``, as it prints it."""
    times = moving["t"]
    i = max(k for k, v in enumerate(times) if v <= t)
    return f"{times[i]:.1f}"
