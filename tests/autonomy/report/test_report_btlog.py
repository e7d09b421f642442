"""Reading tree logs in BehaviorTree.CPP's FileLogger2 format, whole and cut short."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from autonomy.errors import UserError
from autonomy.report import timeline
from autonomy.report.btlog import parse_btlog, read_btlog

XML = """<?xml version="1.0"?>
<root BTCPP_format="4" main_tree_to_execute="Main">
  <BehaviorTree ID="Main" _fullpath="">
    <Sequence name="Mission" _uid="1" _fullpath="Mission">
      <Action ID="Takeoff" name="Takeoff" _uid="2"/>
      <Fallback _uid="3">
        <Condition ID="CheckLandingSite" name="Site known?" _uid="4"/>
      </Fallback>
    </Sequence>
  </BehaviorTree>
  <TreeNodesModel><Action ID="Takeoff"/></TreeNodesModel>
</root>
"""
IDLE, RUNNING, SUCCESS, FAILURE = 0, 1, 2, 3
# (microseconds after the first timestamp, uid, new status)
TRANSITIONS = [(0, 1, RUNNING), (0, 2, RUNNING), (2_500_000, 2, SUCCESS),
               (2_500_000, 3, RUNNING), (2_600_000, 4, FAILURE), (2_600_000, 3, FAILURE),
               (2_600_000, 1, FAILURE)]


def btlog_bytes(transitions=TRANSITIONS, *, magic=True, with_previous=False,
                first_us=1_767_225_600_000_000) -> bytes:
    """A .btlog laid out field by field as bt_file_logger_v2.h describes it."""
    xml = XML.encode()
    out = bytearray(b"BTCPP4-FileLogger2\x01" if magic else b"")
    out += struct.pack("<I", len(xml)) + xml + struct.pack("<q", first_us)
    last: dict[int, int] = {}
    for us, uid, status in transitions:
        byte = status | (last.get(uid, IDLE) << 4 if with_previous else 0)
        out += us.to_bytes(6, "little") + struct.pack("<HB", uid, byte)
        last[uid] = status
    return bytes(out)


@pytest.mark.parametrize("magic, with_previous", [(True, False), (False, True)])
def test_a_btlog_gives_the_tree_and_every_transition(magic, with_previous):
    log = parse_btlog(btlog_bytes(magic=magic, with_previous=with_previous))
    assert [(n.uid, n.name, n.path, n.depth) for n in log.nodes] == [
        (1, "Mission", "Mission", 0), (2, "Takeoff", "Mission/Takeoff", 1),
        (3, "Fallback", "Mission/Fallback", 1),
        (4, "Site known?", "Mission/Fallback/Site known?", 2)]
    assert log.first_timestamp_us == 1_767_225_600_000_000
    assert log.time.tolist() == [us / 1e6 for us, _, _ in TRANSITIONS]
    assert log.uid.tolist() == [u for _, u, _ in TRANSITIONS]
    assert log.status.tolist() == [s for _, _, s in TRANSITIONS]
    assert not log.truncated


def test_a_log_cut_inside_a_transition_replays_to_its_last_whole_one(tmp_path):
    data = btlog_bytes()
    path = tmp_path / "tree.btlog"
    path.write_bytes(data[:-4])
    log = read_btlog(path)
    assert log.truncated
    assert log.uid.tolist() == [u for _, u, _ in TRANSITIONS[:-1]]
    line = timeline.from_btlog(log, offset=10.0, end=20.0)
    # Mission is still running at the cut: its bar lasts to the end of the flight.
    assert [1 - 1, 10.0, 20.0, RUNNING] in line.segments
    assert line.truncated


def test_a_log_cut_before_its_first_timestamp_has_the_tree_and_no_transitions():
    data = btlog_bytes()
    log = parse_btlog(data[: data.index(b"</root>") + len("</root>\n") + 3])
    assert log.truncated and log.time.size == 0 and len(log.nodes) == 4


@pytest.mark.parametrize("cut", [3, 30, 200])
def test_a_log_cut_inside_its_header_is_one_clear_error(cut):
    with pytest.raises(UserError) as err:
        parse_btlog(btlog_bytes()[:cut], "out/tree.btlog")
    message = str(err.value)
    assert message.startswith("out/tree.btlog: ") and "\n" not in message


def test_not_a_btlog_is_one_clear_error(tmp_path):
    path = tmp_path / "tree.btlog"
    path.write_bytes(b"BTCPP4-FileLogger2\x01" + struct.pack("<I", 5) + b"<a><b")
    with pytest.raises(UserError, match=r"tree\.btlog: the tree XML in the log does not parse"):
        read_btlog(path)
    with pytest.raises(UserError, match="cannot read the tree log"):
        read_btlog(tmp_path / "missing.btlog")


def test_transitions_of_unknown_nodes_are_left_out_and_counted():
    log = parse_btlog(btlog_bytes([*TRANSITIONS, (2_700_000, 99, SUCCESS)]))
    assert log.unknown_uids == 1 and 99 not in log.uid.tolist()


def test_timeline_bars_last_until_the_next_transition_and_idle_is_no_bar():
    log = parse_btlog(btlog_bytes([*TRANSITIONS, (3_000_000, 2, IDLE)]))
    line = timeline.from_btlog(log, offset=100.0, end=110.0)
    bars = {(lane, start, end, code) for lane, start, end, code in line.segments}
    assert (1, 100.0, 102.5, RUNNING) in bars  # Takeoff running until it succeeded
    assert (1, 102.5, 103.0, SUCCESS) in bars  # then success until reset to idle
    assert not any(lane == 1 and start >= 103.0 for lane, start, _, _ in bars)
    assert (3, 102.6, 110.0, FAILURE) in bars
    assert np.all([s[1] <= s[2] for s in line.segments])


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
