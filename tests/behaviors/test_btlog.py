"""The tick log (.btlog, BehaviorTree.CPP's FileLogger2 format) and the blackboard log:
written while a mission tree flies, read back through the documented readers, and checked
against BehaviorTree.CPP itself (its XML parser, its uid numbering, its own FileLogger2)."""

from __future__ import annotations

import time
import xml.etree.ElementTree as ET

import numpy as np
import py_trees
import pytest
from behaviors_fakes import FakeVehicle, ScriptedDetector, ScriptedSite, fly
from py_trees.common import Status

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.bblog import BlackboardLogger, read_blackboard_log
from behaviors.btlog import (
    MAGIC,
    TRANSITION_SIZE,
    BtlogError,
    NodeStatus,
    TickLogger,
    Transition,
    node_status,
    read_btlog,
)
from behaviors.settings import LandingSettings, MissionPlan
from behaviors.tree import build_mission_tree
from behaviors.treexml import instance_xml, preorder
from lsm import LandingSiteManager, LsmSettings


def _flown(tmp_path, sites, landing=None):
    """Fly the landing mission with the fakes, logging it; returns (tree, log path,
    blackboard log path, statuses after every tick by uid)."""
    plan = MissionPlan(waypoints=[(0, 0, 100), (150, 0, 100)],
                       landing=LandingSettings(**(landing or {})))
    clock = SimClock()
    vehicle = FakeVehicle(clock)
    lsm = LandingSiteManager(LsmSettings(max_distance=150.0))
    tree = build_mission_tree(plan, vehicle, lsm, clock, np.random.default_rng(0))
    path, board_path = tmp_path / "tree.btlog", tmp_path / "blackboard.jsonl"
    ticks = TickLogger(path, tree.root, instance_xml(tree), clock.now).attach(tree)
    board = BlackboardLogger(board_path, keys.KEYS, clock.now).attach(tree)
    nodes = list(preorder(tree.root))
    after: list[tuple[float, list[Status]]] = []
    tree.add_post_tick_handler(
        lambda t: after.append((clock.now(), [n.status for n in nodes])))
    flight = fly(tree, vehicle, clock, lsm, ScriptedDetector(list(sites), footprint=0.3))
    ticks.close()
    board.close()
    return tree, flight, path, board_path, after


def test_btlog_replays_every_tick_of_a_flight_with_a_failed_verification(tmp_path):
    sites = [ScriptedSite(120.0, 10.0, roughness=0.05, fails_verification=True),
             ScriptedSite(80.0, -20.0, roughness=0.3)]
    tree, flight, path, _, after = _flown(tmp_path, sites)
    assert flight.status == Status.SUCCESS

    log = read_btlog(path)

    assert not log.truncated and log.first_timestamp == 0.0
    # The XML numbers the nodes 1.. in the tree's pre-order, with their names.
    nodes = list(preorder(tree.root))
    assert sorted(log.nodes) == list(range(1, len(nodes) + 1))
    assert [log.nodes[i + 1].name for i in range(len(nodes))] == [n.name for n in nodes]
    assert log.nodes[1].parent is None
    assert log.nodes[2].parent == 1
    # Replaying the transitions gives every node's status after every tick.
    for t, statuses in after[:: max(1, len(after) // 200)] + after[-1:]:
        replayed = log.statuses_at(t + 1e-9)
        assert [replayed[i + 1] for i in range(len(nodes))] == [
            node_status(s) for s in statuses], t
    times = [tr.time for tr in log.transitions]
    assert times == sorted(times)
    assert log.transitions[-1].uid == 1 and log.transitions[-1].status is NodeStatus.SUCCESS
    # The failed verification is in the log, with the clock's time.
    verification = next(u for u, n in log.nodes.items() if n.name == "LandingSiteVerification")
    outcomes = [tr for tr in log.transitions if tr.uid == verification
                and tr.status in (NodeStatus.FAILURE, NodeStatus.SUCCESS)]
    assert [tr.status for tr in outcomes] == [NodeStatus.FAILURE, NodeStatus.SUCCESS]
    assert 0 < outcomes[0].time < outcomes[1].time <= after[-1][0]


def test_a_btlog_cut_short_reads_to_its_last_whole_transition(tmp_path):
    _, _, path, board_path, _ = _flown(tmp_path, [ScriptedSite(120.0, 10.0)])
    whole = read_btlog(path)
    data = path.read_bytes()
    cut = tmp_path / "cut.btlog"
    cut.write_bytes(data[:-(TRANSITION_SIZE * 3 + 4)])

    short = read_btlog(cut)

    assert short.truncated
    assert short.transitions == whole.transitions[:-4]
    cut.write_bytes(data[:40])
    with pytest.raises(BtlogError, match="cut short inside its header"):
        read_btlog(cut)
    cut.write_bytes(b"not a log")
    with pytest.raises(BtlogError, match="not a BehaviorTree.CPP FileLogger2 log"):
        read_btlog(cut)
    corrupt = bytearray(data)
    corrupt[-1] = 65  # the last transition's status byte
    cut.write_bytes(bytes(corrupt))
    with pytest.raises(BtlogError, match=r"transition \d+ has status 65, which is no node"):
        read_btlog(cut)
    # The blackboard log: start values, then changes; a torn last line is left out.
    entries = read_blackboard_log(board_path)
    assert [e["key"] for e in entries[: len(keys.KEYS)]] == list(keys.KEYS)
    chosen = [e for e in entries if e["key"] == keys.LANDING_SITE and e["value"]]
    assert chosen and chosen[-1]["value"]["x"] == pytest.approx(120.0, abs=1.0)
    assert [e["value"] for e in entries if e["key"] == keys.PHASE][-1] == "done"
    text = board_path.read_text()
    board_path.write_text(text[:-10])
    assert read_blackboard_log(board_path) == entries[:-1]


# --- BehaviorTree.CPP as the oracle --------------------------------------------------

btcpp = pytest.importorskip("behaviortreepy", reason="BehaviorTree.CPP's Python binding")
BTCPP_BUILTINS = {"Sequence", "Fallback", "ReactiveSequence", "ReactiveFallback", "Parallel",
                  "RetryUntilSuccessful", "Inverter", "SubTree"}


def btcpp_tree(xml: str):
    """BehaviorTree.CPP's own tree from our XML: our nodes registered as plain actions
    and decorators (the binding cannot declare their ports, so port attributes are left
    out); BehaviorTree.CPP parses, checks and numbers the rest."""
    root = ET.fromstring(xml)
    factory = btcpp.BehaviorTreeFactory()
    for tag, leaf in {(e.tag, not len(e)) for e in root.iter() if e.get("_uid")}:
        if tag in BTCPP_BUILTINS:
            continue
        if leaf:
            factory.register_simple_action(tag, lambda node: btcpp.NodeStatus.SUCCESS)
        else:
            factory.register_simple_decorator(tag, lambda status, node: status)
    main = root.get("main_tree_to_execute")
    for element in [e for tree in root.findall("BehaviorTree") for e in tree.iter()]:
        for name in [k for k in element.attrib if k not in ("ID", "name")]:
            del element.attrib[name]
    factory.register_behavior_tree_from_text(ET.tostring(root, encoding="unicode"))
    return factory.create_tree(main)


def test_behaviortree_cpp_numbers_our_tree_as_our_log_does_and_its_log_reads(tmp_path):
    plan = MissionPlan(waypoints=[(0, 0, 100), (150, 0, 100)])
    clock = SimClock()
    tree = build_mission_tree(plan, FakeVehicle(clock), LandingSiteManager(LsmSettings()),
                              clock, np.random.default_rng(0))
    ours = instance_xml(tree)

    theirs = btcpp_tree(ours)
    logger = btcpp.FileLogger(theirs, str(tmp_path / "btcpp.btlog"))
    assert theirs.tick_once() == btcpp.NodeStatus.SUCCESS
    # Its writer thread moves the queue into the file stream every 10 ms; flush() from this
    # thread would race it on the same stream (and tear the file), and the destructor drops
    # what is still queued. So: give the thread time, then close the file.
    time.sleep(1.0)
    del logger

    data = (tmp_path / "btcpp.btlog").read_bytes()
    assert data.startswith(MAGIC + b"\x01")
    log = read_btlog(tmp_path / "btcpp.btlog")
    # BehaviorTree.CPP gave each node the uid our XML gives it.
    mine = read_btlog_nodes(ours)
    assert {u: (n.tag, n.name) for u, n in log.nodes.items()} == mine
    # Its transitions read back: every node it ticked went to SUCCESS.
    assert log.transitions and {t.uid for t in log.transitions} <= set(mine)
    assert log.transitions[-1].status is NodeStatus.SUCCESS or any(
        t.uid == 1 and t.status is NodeStatus.SUCCESS for t in log.transitions)
    assert abs(log.first_timestamp - time.time()) < 60  # it writes wall-clock time


def read_btlog_nodes(xml: str) -> dict[int, tuple[str, str]]:
    from behaviors.btlog import parse_nodes

    return {u: (n.tag, n.name) for u, n in parse_nodes(xml).items()}


def test_the_clock_not_the_wall_stamps_the_log(tmp_path):
    clock = SimClock()
    clock.advance(1000.0)
    root = py_trees.behaviours.Success(name="ok")
    tree = py_trees.trees.BehaviourTree(root)
    logger = TickLogger(tmp_path / "t.btlog", root, instance_xml(tree), clock.now).attach(tree)
    clock.advance(2.5)
    tree.tick()
    # Each tick is on disk when it ends: a flight killed now leaves a whole log.
    assert read_btlog(tmp_path / "t.btlog").transitions == [
        Transition(pytest.approx(2.5), 1, NodeStatus.SUCCESS)]
    logger.close()
    log = read_btlog(tmp_path / "t.btlog")
    assert log.first_timestamp == 1000.0
    assert [(t.time, t.uid, t.status) for t in log.transitions] == [
        (pytest.approx(2.5), 1, NodeStatus.SUCCESS)]


def test_a_mission_flying_its_own_tree_file_writes_its_tick_log(tmp_path):
    # missions/skip_search.yaml flies missions/skip_search.xml (a subtree, no search).
    from autonomy.config import load_mission
    from autonomy.runner import fly as fly_mission

    result = fly_mission(load_mission("missions/skip_search.yaml"), out_dir=tmp_path)

    assert result.outcome == "landed"
    assert (result.data.verification_attempts, result.data.search_patterns) == (2, 0)
    log = read_btlog(tmp_path / "tree.btlog")
    assert log.nodes[1].name == "Survey then land" and not log.truncated
    subtree = log.nodes[2]
    assert (subtree.tag, subtree.name, subtree.attributes["_fullpath"]) == (
        "SubTree", "Failsafe", "Failsafe::2")
    assert log.nodes[3].parent == 2 and log.nodes[3].name == "Failsafe"
    assert "Survey point 3" in {n.name for n in log.nodes.values()}
    # The root's last transition is the flight's end, at the simulated time it landed.
    last = [t for t in log.transitions if t.uid == 1][-1]
    assert last.status is NodeStatus.SUCCESS
    assert last.time == pytest.approx(result.data.end_time, abs=0.11)
    phases = [e["value"] for e in read_blackboard_log(tmp_path / "blackboard.jsonl")
              if e["key"] == keys.PHASE]
    assert phases[0] == "preflight" and phases[-1] == "done"
