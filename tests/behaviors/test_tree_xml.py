"""Trees as data: the built-in landing tree, loaded from its XML file, flies tick for tick
as the Python builder it replaced; tree files round-trip; BehaviorTree.CPP accepts what we
write; bad tree files fail with file, line, node and port."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import py_trees
import pytest
from behaviors_fakes import FakeVehicle, ScriptedDetector, ScriptedSite, fly
from behaviors_legacy_tree import legacy_mission_tree

from autonomy.clock import SimClock
from behaviors import blackboard as keys
from behaviors.loader import BUILTIN_TREE, TreeFileError, check_tree, parse_tree, read_tree
from behaviors.registry import REGISTRY, mission_settings
from behaviors.settings import LandingSettings, MissionPlan
from behaviors.tree import build_mission_tree
from behaviors.treexml import instance_xml, preorder, source_xml
from lsm import LandingSiteManager, LsmSettings

GOOD = ScriptedSite(120.0, 10.0, roughness=0.05)
POOR = ScriptedSite(60.0, -15.0, roughness=0.7, size=1.0)
FALSE = ScriptedSite(120.0, 10.0, roughness=0.05, fails_verification=True)
SECOND = ScriptedSite(80.0, -20.0, roughness=0.3, obstacle_altitude=12.0)
BESIDE = ScriptedSite(124.0, 10.0, roughness=0.5)


def drain(rate):
    """A battery falling by ``rate`` % per tick."""
    return lambda vehicle, tick: setattr(vehicle, "battery", max(0.0, 100.0 - rate * tick))


def lose_gps(at):
    return lambda vehicle, tick: setattr(vehicle, "gps_fix", 0 if tick >= at else 3)


SCENARIOS = {
    "nominal": dict(sites=[GOOD, POOR]),
    "failed verification, next site": dict(sites=[FALSE, SECOND]),
    "no site: searches, new pattern centres, land in place": dict(
        sites=[], landing=dict(pattern_retries=2, landing_retries=2,
                                 search_rectangle=(30.0, 20.0))),
    "verification off": dict(sites=[GOOD], landing=dict(verify=False)),
    "last resort on a verified site": dict(sites=[FALSE, BESIDE], footprint=2.0,
                                           landing=dict(landing_retries=1)),
    "battery drains: no room for another try, land in place": dict(
        sites=[FALSE, SECOND], each_tick=drain(0.1)),
    "battery drains faster: critical failsafe": dict(
        sites=[FALSE, SECOND], each_tick=drain(0.15)),
    "gps lost": dict(sites=[GOOD], each_tick=lose_gps(300)),
    "goto denied": dict(sites=[GOOD], vehicle=dict(deny={"goto": "not in GUIDED"})),
}


def trace(build, scenario, tree_file=None):
    """Per tick, every node's (name, status) in pre-order; then the vehicle's commands and
    the blackboard at the end."""
    plan = MissionPlan(waypoints=[(0, 0, 100), (150, 0, 100)],
                       landing=LandingSettings(**scenario.get("landing", {})))
    clock = SimClock()
    vehicle = FakeVehicle(clock, **scenario.get("vehicle", {}))
    lsm = LandingSiteManager(LsmSettings(max_distance=150.0))
    args = (plan, vehicle, lsm, clock, np.random.default_rng(7))
    tree = build(*args) if tree_file is None else build(*args, tree_file)
    nodes = list(preorder(tree.root))
    ticks: list[tuple] = []
    tree.add_post_tick_handler(
        lambda t: ticks.append(tuple((n.name, n.status) for n in nodes)))
    each_tick = scenario.get("each_tick")
    flight = fly(tree, vehicle, clock, lsm, ScriptedDetector(list(scenario["sites"]),
                                                          scenario.get("footprint", 0.3)),
                 on_tick=None if each_tick is None else lambda k: each_tick(vehicle, k),
                 max_time=1500.0)
    return ticks, vehicle.commands, keys.read_all(), flight.status, tree


@pytest.mark.parametrize("name", SCENARIOS)
def test_the_xml_tree_flies_tick_for_tick_as_the_python_builder(name):
    scenario = SCENARIOS[name]
    old_ticks, old_commands, old_board, old_status, _ = trace(legacy_mission_tree, scenario)
    py_trees.blackboard.Blackboard.clear()
    new_ticks, new_commands, new_board, new_status, _ = trace(build_mission_tree, scenario)

    assert len(new_ticks) == len(old_ticks)
    for k, (old, new) in enumerate(zip(old_ticks, new_ticks, strict=True)):
        assert new == old, f"tick {k}"
    assert new_commands == old_commands
    assert new_board == old_board
    assert new_status == old_status
    # The comparison means something only if the scenario flies the branch it is about.
    assert (new_status.name, new_board[keys.OUTCOME_HINT], new_board[keys.BANNED_SITES],
            new_board[keys.SEARCH_PATTERNS]) == EXPECTED[name]


EXPECTED = {  # status, outcome hint, sites banned, search patterns flown
    "nominal": ("SUCCESS", None, 0, 0),
    "failed verification, next site": ("SUCCESS", None, 1, 0),
    # 2 tries x (1 search + 2 at new centres)
    "no site: searches, new pattern centres, land in place": ("SUCCESS", "no_site", 0, 6),
    "verification off": ("SUCCESS", None, 0, 0),
    "last resort on a verified site": ("SUCCESS", "verified_site", 1, 0),
    "battery drains: no room for another try, land in place": ("SUCCESS", "no_site", 1, 0),
    "battery drains faster: critical failsafe": ("SUCCESS", "battery_critical", 0, 0),
    "gps lost": ("SUCCESS", "gps_lost", 0, 0),
    "goto denied": ("FAILURE", None, 0, 0),
}


def test_the_built_in_tree_file_round_trips_and_carries_the_current_node_models():
    text = BUILTIN_TREE.read_text(encoding="utf-8")
    assert source_xml(parse_tree(text, "landing_tree.xml")) == text


def test_a_built_trees_instance_xml_builds_the_same_tree_again(tmp_path):
    scenario = SCENARIOS["failed verification, next site"]
    ticks, commands, _, _, tree = trace(build_mission_tree, scenario)
    written = tmp_path / "instance.xml"
    written.write_text(instance_xml(tree), encoding="utf-8")
    py_trees.blackboard.Blackboard.clear()
    again_ticks, again_commands, _, _, again = trace(build_mission_tree, scenario, written)
    assert instance_xml(again) == instance_xml(tree)
    assert (again_ticks, again_commands) == (ticks, commands)


# --- BehaviorTree.CPP as the oracle --------------------------------------------------

btcpp = pytest.importorskip("behaviortreepy", reason="BehaviorTree.CPP's Python binding")


def btcpp_factory():
    """BehaviorTree.CPP's factory with our registered nodes (its builtins stand for ours of
    the same name; the binding cannot declare ports, so it checks structure only)."""
    factory = btcpp.BehaviorTreeFactory()
    for node_id, model in REGISTRY.items():
        if node_id in ("Sequence", "ReactiveSequence", "Fallback", "ReactiveFallback",
                       "Parallel", "Inverter", "RetryUntilSuccessful", "SubTree"):
            continue
        if model.kind == "Action":
            factory.register_simple_action(node_id, lambda node: btcpp.NodeStatus.SUCCESS)
        elif model.kind == "Condition":
            factory.register_simple_condition(node_id, lambda node: btcpp.NodeStatus.SUCCESS)
        else:
            assert model.kind == "Decorator", node_id
            factory.register_simple_decorator(node_id, lambda status, node: status)
    return factory


@pytest.mark.parametrize("tree", ["landing_tree.xml", "missions/skip_search.xml"])
def test_behaviortree_cpp_parses_our_tree_files(tree):
    path = BUILTIN_TREE if tree == "landing_tree.xml" else tree
    factory = btcpp_factory()
    factory.register_behavior_tree_from_text(source_xml(read_tree(path)))
    assert read_tree(path).main in factory.registered_behavior_trees()


def test_behaviortree_cpp_refuses_what_our_checker_refuses():
    # The same mistake caught by both: an unknown node.
    bad = ('<root BTCPP_format="4"><BehaviorTree ID="T"><Sequence><Lnd/></Sequence>'
           '</BehaviorTree></root>')
    with pytest.raises(Exception, match="Lnd"):
        btcpp_factory().register_behavior_tree_from_text(bad)
    settings = mission_settings(MissionPlan(waypoints=[(0, 0, 10)]), 1.0)
    assert check_tree(parse_tree(bad, "bad.xml"), settings) == [
        "bad.xml:1: Lnd: unknown node (see `lander tree --xml` for the registered ones); "
        "did you mean Land?"]


def test_every_model_is_a_valid_treenodesmodel_entry():
    models = ET.fromstring(source_xml(read_tree(BUILTIN_TREE))).find("TreeNodesModel")
    ids = [m.get("ID") for m in models]
    assert ids == sorted(ids) and "SubTree" not in ids
    assert {m.tag for m in models} <= {"Action", "Condition", "Control", "Decorator"}
    land = next(m for m in models if m.get("ID") == "Land")
    assert [(p.tag, p.get("name"), p.get("type")) for p in land if p.tag.endswith("port")] == [
        ("input_port", "command_timeout", "double"), ("input_port", "outcome_hint",
                                                      "std::string"),
        ("input_port", "phase", "std::string")]


# --- tree files through the CLI -------------------------------------------------------

BAD_TREE = """<root BTCPP_format="4" main_tree_to_execute="A">
  <BehaviorTree ID="A">
    <Sequence name="Main">
      <Lnd name="typo"/>
      <Land name="Touch down" phase="landing" colour="red"/>
      <ClockTimeout seconds="soon"><Takeoff/></ClockTimeout>
      <NavigateToWaypoint name="Third" waypoint="{waypoint_3}"/>
      <NavigateToWaypoint />
      <NavigateToSite site="12"/>
      <SubTree ID="B"/>
    </Sequence>
  </BehaviorTree>
  <BehaviorTree ID="B"><SubTree ID="C"/></BehaviorTree>
  <BehaviorTree ID="C"><SubTree ID="B"/></BehaviorTree>
</root>
"""


def test_lander_validate_names_file_line_node_and_port_of_each_problem(tmp_path, capsys):
    from autonomy.cli import main

    (tmp_path / "trees").mkdir()
    (tmp_path / "trees" / "bad.xml").write_text(BAD_TREE)
    mission = tmp_path / "m.yaml"
    mission.write_text("waypoints: [[0, 0, 20], [10, 0, 20]]\ntree: trees/bad.xml\n")

    assert main(["validate", str(mission)]) == 2

    tree = tmp_path / "trees" / "bad.xml"
    assert capsys.readouterr().err.splitlines() == [f"lander validate: error: {tree}:{line}"
                                                    f": {text}" for line, text in [
        (4, "Lnd: unknown node (see `lander tree --xml` for the registered ones); did you "
            "mean Land?"),
        (5, "Land 'Touch down': port colour: Land has no such port (its ports: phase, "
            "outcome_hint, command_timeout)"),
        (5, "Land 'Touch down': port phase: 'landing' is not a phase (preflight, takeoff, "
            "mission, landing_phase, search, navigate_to_site, descend, verification, centre, "
            "land, land_in_place, failsafe, done)"),
        (6, "ClockTimeout: port seconds: 'soon' is not a number (double, s)"),
        (7, "NavigateToWaypoint 'Third': port waypoint: the mission has no setting "
            "{waypoint_3} (it has 2 waypoints)"),
        (8, "NavigateToWaypoint: port waypoint: required (Point3D, m: ENU x;y;z (z above "
            "home))"),
        (9, "NavigateToSite: port site: takes a blackboard entry {name}, not a literal "
            "(LandingSite)"),
        (14, "SubTree 'B': cycle of subtrees: B -> C -> B"),
    ]]
    # A tree file that is not there is the mission file's problem, at its line.
    mission.write_text("waypoints: [[0, 0, 20]]\n\ntree: nowhere.xml\n")
    assert main(["validate", str(mission)]) == 2
    assert capsys.readouterr().err == (
        f"lander validate: error: {mission}:3: tree: cannot read tree file "
        f"'{tmp_path / 'nowhere.xml'}': no such file\n")
    mission.write_text('waypoints: [[0, 0, 20]]\ntree: "a\\0b.xml"\n')
    assert main(["validate", str(mission)]) == 2
    assert capsys.readouterr().err.startswith(
        f"lander validate: error: {mission}:2: tree: cannot read tree file '")
    (tmp_path / "broken.xml").write_text("<root BTCPP_format='4'>\n<BehaviorTree ID='A'>\n")
    mission.write_text("waypoints: [[0, 0, 20]]\ntree: broken.xml\n")
    assert main(["validate", str(mission)]) == 2
    assert capsys.readouterr().err == (
        f"lander validate: error: {tmp_path / 'broken.xml'}:3: XML syntax error: "
        "no element found\n")


def test_lander_tree_writes_the_tree_file_groot2_opens(tmp_path, capsys):
    from autonomy.cli import main

    assert main(["validate", "missions/skip_search.yaml"]) == 0
    assert capsys.readouterr().out.rstrip().endswith(", tree missions/skip_search.xml")
    assert main(["tree", "missions/demo.yaml", "--xml", str(tmp_path / "landing.xml")]) == 0
    assert (tmp_path / "landing.xml").read_text() == BUILTIN_TREE.read_text()
    assert "LandingSiteSearch within 300 s" in capsys.readouterr().out
    assert main(["tree", "missions/skip_search.yaml", "--xml", str(tmp_path / "s.xml")]) == 0
    out = capsys.readouterr().out
    assert "Survey point 3 within 300 s" in out and "Search" not in out
    written = read_tree(tmp_path / "s.xml")
    assert written.main == "SurveyThenLand" and set(written.trees) == {"SurveyThenLand",
                                                                       "Failsafe"}
    assert ET.parse(tmp_path / "s.xml").getroot().find("TreeNodesModel/Action[@ID='Land']") \
        is not None


def test_check_tree_refuses_structural_mistakes_in_one_line_each():
    settings = mission_settings(MissionPlan(waypoints=[(0, 0, 10)]), 1.0)
    with pytest.raises(TreeFileError) as caught:
        parse_tree('<root BTCPP_format="4"><BehaviorTree ID="A"/><BehaviorTree ID="Land">'
                   '<Land/></BehaviorTree></root>', "x.xml")
    assert caught.value.problems == [
        "x.xml:1: BehaviorTree 'A': needs exactly one root node, has 0",
        "x.xml:1: BehaviorTree 'Land': the ID of a registered node"]
    skipped = parse_tree('<root BTCPP_format="4"><BehaviorTree ID="A"><Inverter>'
                         '<Land _skipIf="verify"/></Inverter></BehaviorTree></root>', "y.xml")
    assert check_tree(skipped, settings) == [
        "y.xml:1: Inverter: its child is left out (_skipIf) or unknown"]
    # A node needing what the mission does not provide.
    watched = parse_tree('<root BTCPP_format="4"><BehaviorTree ID="A">\n<WatchedDescent '
                         'name="Down"/></BehaviorTree></root>', "z.xml")
    assert check_tree(watched, settings) == [
        "z.xml:2: WatchedDescent 'Down': needs a descent camera's obstacle watch "
        "(behaviors.ports.ObstacleWatch), which this mission does not provide"]
    assert check_tree(watched, settings, {"obstacle_watch"}) == []


def test_the_node_registry_page_lists_every_registered_node():
    from pathlib import Path

    page = Path("docs/trees.md").read_text(encoding="utf-8")
    missing = [node_id for node_id in REGISTRY if f"`{node_id}`" not in page]
    assert not missing
