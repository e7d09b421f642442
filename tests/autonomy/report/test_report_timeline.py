"""The tree's timeline of report.html, from a tree.btlog (whole or cut short) or from the
tree events of events.jsonl."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from autonomy.report import timeline
from autonomy.report.page import tree_timeline
from behaviors.btlog import read_btlog

XML = """<?xml version="1.0"?>
<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main" _fullpath="">
    <Sequence name="Mission" _uid="1">
      <Takeoff name="Takeoff" _uid="2"/>
      <Fallback _uid="3">
        <CheckLandingSite name="Site known?" _uid="4"/>
      </Fallback>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel><Action ID="Takeoff"/></TreeNodesModel>
</root>
"""
IDLE, RUNNING, SUCCESS, FAILURE = 0, 1, 2, 3
# (microseconds after the first timestamp, uid, new status)
TRANSITIONS = [(0, 1, RUNNING), (0, 2, RUNNING), (2_500_000, 2, SUCCESS),
               (2_500_000, 3, RUNNING), (2_600_000, 4, RUNNING), (2_600_000, 4, FAILURE),
               (2_600_000, 3, FAILURE), (2_600_000, 1, FAILURE)]


def btlog_bytes(transitions=TRANSITIONS, first_us=100_000_000) -> bytes:
    """A .btlog laid out field by field as BehaviorTree.CPP's bt_file_logger_v2.h says."""
    xml = XML.encode()
    out = bytearray(b"BTCPP4-FileLogger2\x01")
    out += struct.pack("<i", len(xml)) + xml + struct.pack("<q", first_us)
    for us, uid, status in transitions:
        out += us.to_bytes(6, "little") + struct.pack("<HB", uid, status)
    return bytes(out)


def test_bars_last_until_the_next_transition_at_clock_time(tmp_path):
    path = tmp_path / "tree.btlog"
    path.write_bytes(btlog_bytes([*TRANSITIONS, (3_000_000, 2, IDLE)]))
    line = timeline.from_btlog(read_btlog(path), end=110.0)
    assert [(lane["name"], lane["path"], lane["depth"]) for lane in line.lanes] == [
        ("Mission", "Mission", 0), ("Takeoff", "Mission/Takeoff", 1),
        ("Fallback", "Mission/Fallback", 1), ("Site known?", "Mission/Fallback/Site known?", 2)]
    bars = {tuple(s) for s in line.segments}
    assert (1, 100.0, 102.5, RUNNING) in bars  # the first timestamp is clock time 100 s
    assert (1, 102.5, 103.0, SUCCESS) in bars  # then success until reset to idle: no bar
    assert not any(lane == 1 and start >= 103.0 for lane, start, _, _ in bars)
    assert (0, 102.6, 110.0, FAILURE) in bars
    # Running and failing within one tick shows as the failure alone.
    assert [s for s in bars if s[0] == 3] == [(3, 102.6, 110.0, FAILURE)]
    assert np.all([s[1] <= s[2] for s in line.segments]) and not line.truncated


def test_a_log_cut_inside_a_transition_shows_the_tree_to_its_last_whole_one(tmp_path):
    (tmp_path / "tree.btlog").write_bytes(btlog_bytes(TRANSITIONS[:3])[:-4])
    tree, note = tree_timeline([], 105.0, tmp_path)
    assert note is None and tree["source"] == "tree.btlog" and tree["truncated"]
    # Takeoff's SUCCESS was cut: it is still running at the end of what was logged.
    assert sorted(tree["segments"]) == [[0, 100.0, 105.0, RUNNING], [1, 100.0, 105.0, RUNNING]]


@pytest.mark.parametrize("cut", [3, 30, 300])
def test_a_log_cut_inside_its_header_falls_back_to_the_events_and_says_so(tmp_path, cut):
    (tmp_path / "tree.btlog").write_bytes(btlog_bytes()[:cut])
    events = [{"t": 0.1, "kind": "tree", "path": "Root", "old": "INVALID", "new": "RUNNING"}]
    tree, note = tree_timeline(events, 1.0, tmp_path)
    assert tree["source"] == "events.jsonl" and tree["segments"] == [[0, 0.1, 1.0, RUNNING]]
    assert note.startswith("tree.btlog unreadable (") and "\n" not in note


def test_timeline_from_events_puts_parents_before_children():
    events = [
        {"t": 0.1, "kind": "tree", "path": "Root/A/leaf", "old": "INVALID", "new": "RUNNING"},
        {"t": 0.1, "kind": "tree", "path": "Root/A", "old": "INVALID", "new": "RUNNING"},
        {"t": 0.1, "kind": "tree", "path": "Root", "old": "INVALID", "new": "RUNNING"},
        {"t": 0.5, "kind": "tree", "path": "Root/B", "old": "INVALID", "new": "FAILURE"},
        {"t": 0.5, "kind": "lsm", "decision": "inserted", "site": 1},
    ]
    line = timeline.from_events(events, end=1.0)
    assert [lane["path"] for lane in line.lanes] == ["Root", "Root/A", "Root/A/leaf", "Root/B"]
    assert [lane["depth"] for lane in line.lanes] == [0, 1, 2, 1]
    assert sorted(line.segments) == [[0, 0.1, 1.0, 1], [1, 0.1, 1.0, 1], [2, 0.1, 1.0, 1],
                                     [3, 0.5, 1.0, 3]]
