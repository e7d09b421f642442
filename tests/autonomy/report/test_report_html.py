"""report.html of a real flight: what it holds, and how it behaves in headless Chromium."""

from __future__ import annotations

import json
import re
import shutil
import struct

import numpy as np
import pytest

from autonomy.report import write_flight_page
from autonomy.report.page import build_page, loss_terms


def embedded(path):
    """The flight data a report.html embeds."""
    text = path.read_text(encoding="utf-8")
    match = re.search(r'<script id="flight-data" type="application/json">(.*?)</script>',
                      text, re.S)
    return json.loads(match.group(1))


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
    assert page["tree"]["source"] == "events.jsonl"
    assert page["map"] is not None and page["map"]["href"].startswith("data:image/png;base64,")
    assert page["end"] == pytest.approx(summary["mission_time"])


def _btlog_from_events(events, path, cut=0):
    """A FileLogger2 .btlog of the flight's tree events (uids in lane order), as a writer
    following bt_file_logger_v2.h lays it out."""
    paths = []
    for e in events:
        if e["kind"] == "tree" and e["path"] not in paths:
            paths.append(e["path"])
    xml = "<root BTCPP_format=\"4\"><BehaviorTree ID=\"Main\">" + "".join(
        f"<Action name=\"{p.replace('&', '&amp;').replace('<', '&lt;')}\" _uid=\"{i + 1}\"/>"
        for i, p in enumerate(paths)) + "</BehaviorTree></root>"
    codes = {"INVALID": 0, "RUNNING": 1, "SUCCESS": 2, "FAILURE": 3}
    first = next(e["t"] for e in events if e["kind"] == "tree")
    out = bytearray(b"BTCPP4-FileLogger2\x01")
    out += struct.pack("<I", len(xml.encode())) + xml.encode() + struct.pack("<q", 0)
    for e in events:
        if e["kind"] == "tree":
            us = round((e["t"] - first) * 1e6)
            out += us.to_bytes(6, "little") + struct.pack(
                "<HB", paths.index(e["path"]) + 1, codes[e["new"]])
    path.write_bytes(bytes(out[:len(out) - cut]))
    return paths


def test_a_btlog_beside_the_report_gives_the_tree_timeline(demo_flight, tmp_path):
    out = tmp_path / "flight"
    shutil.copytree(demo_flight.out_dir, out)
    paths = _btlog_from_events(demo_flight.events, out / "tree.btlog")
    write_flight_page(demo_flight.data, demo_flight.summary, demo_flight.events, out)
    page = embedded(out / "report.html")
    from_events = build_page(demo_flight.data, demo_flight.summary, demo_flight.events)
    assert page["tree"]["source"] == "tree.btlog" and not page["tree"]["truncated"]
    assert [lane["name"] for lane in page["tree"]["lanes"]] == paths
    # The same flight, the same bars, whichever log they came from (lanes ordered alike).
    lane_of = {lane["path"]: i for i, lane in enumerate(from_events["tree"]["lanes"])}
    expected = sorted([lane_of[paths[int(lane)]], t0, t1, code]
                      for lane, t0, t1, code in page["tree"]["segments"])
    assert expected == sorted(from_events["tree"]["segments"])

    # Cut short inside its last transition: shown up to the one before, and said so.
    _btlog_from_events(demo_flight.events, out / "tree.btlog", cut=5)
    write_flight_page(demo_flight.data, demo_flight.summary, demo_flight.events, out)
    cut = embedded(out / "report.html")
    assert cut["tree"]["truncated"]
    assert len(cut["tree"]["segments"]) == len(page["tree"]["segments"]) - 1


def test_report_html_loads_in_chromium_without_errors_and_shows_the_loss_terms(
        demo_flight, chromium):
    import browser

    page = demo_flight.out_dir / "report.html"
    chosen = demo_flight.data.chosen_site
    takeoff = next(t for t, p in demo_flight.data.trace.phases if p == "mission")
    report = browser.inspect_page(chromium, page.resolve().as_uri(), [
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
    assert len(np.unique(image.reshape(-1, 3), axis=0)) > 50
