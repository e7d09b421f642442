"""The mission file: schema, file:line:field messages, derived defaults, overrides."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from pydantic import ValidationError

from autonomy.config import (
    Mission,
    MissionFileError,
    apply_overrides,
    geodetic_to_enu,
    load_mission,
)
from autonomy.errors import UserError

REPO = Path(__file__).resolve().parents[2]

GOOD = """\
name: t
cruise_altitude: 40
waypoints:
  - [10, 0, 30]
  - {lat: 47.398742, lon: 8.545594}
"""


def write(tmp_path: Path, text: str, name: str = "m.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def problems(path: Path) -> list[str]:
    with pytest.raises(MissionFileError) as info:
        load_mission(path)
    assert isinstance(info.value, UserError)
    return info.value.problems


def test_good_file_converts_geodetic_waypoints_about_home(tmp_path):
    mission = load_mission(write(tmp_path, GOOD))
    (x0, y0, z0), (x1, y1, z1) = mission.waypoints_enu()
    assert (x0, y0, z0) == (10.0, 0.0, 30.0)
    # 0.001 deg of latitude north of the default home is about 111 m north.
    assert abs(x1) < 0.01 and 110.0 < y1 < 112.0
    assert z1 == 40.0  # no alt: cruise altitude
    plan = mission.plan()
    assert plan.waypoints[1] == pytest.approx((x1, y1, z1))
    assert plan.cruise_altitude == 40.0


def test_geodetic_to_enu_east_at_the_equator():
    east, north = geodetic_to_enu(0.0, 0.001, 0.0, 0.0)
    assert east == pytest.approx(6378137.0 * math.radians(0.001), rel=1e-6)
    assert abs(north) < 1e-6


def test_normaliser_and_verification_altitude_follow_unless_set(tmp_path):
    mission = load_mission(write(tmp_path, GOOD + "landing: {verification_altitude: 4}\n"))
    assert mission.weights.normaliser == 40.0
    assert mission.lsm.verification_altitude == 4.0
    explicit = load_mission(write(
        tmp_path, GOOD + "weights: {normaliser: 70}\nlsm: {verification_altitude: 3}\n"
    ))
    assert explicit.weights.normaliser == 70.0
    assert explicit.lsm.verification_altitude == 3.0


def test_every_problem_is_one_message_with_file_line_and_field(tmp_path):
    path = write(tmp_path, """\
waypoints:
  - [0, 50, -30]
  - {lat: 100, lon: 3}
landing:
  verification_altitude: -1
  bogus: 3
cruise_altitude: abc
vehicle: {autopilot: inav}
sites:
  - {x: 1}
""")
    found = problems(path)
    expected = [
        (2, "waypoints.0.2"),
        (3, "waypoints.1.lat"),
        (5, "landing.verification_altitude"),
        (6, "landing.bogus"),
        (7, "cruise_altitude"),
        (8, "vehicle.autopilot"),
        (10, "sites.0.y"),
    ]
    assert len(found) == len(expected)
    for message, (line, field) in zip(found, expected, strict=True):
        assert message.startswith(f"{path}:{line}: {field}: "), message
    assert "unknown setting" in found[3]
    assert "'abc'" in found[4]


def test_missing_waypoints_names_the_field(tmp_path):
    (message,) = problems(write(tmp_path, "name: x\n"))
    assert message.endswith("waypoints: required")


def test_yaml_syntax_error_names_its_line(tmp_path):
    (message,) = problems(write(tmp_path, "name: x\nwaypoints: [[1, 2, 3]\nseed: 1\n"))
    assert message.startswith(f"{tmp_path / 'm.yaml'}:3: YAML syntax error")


def test_duplicate_keys_empty_and_non_mapping_files(tmp_path):
    (dup,) = problems(write(tmp_path, GOOD + "cruise_altitude: 50\n"))
    assert dup.endswith(":6: cruise_altitude: duplicate key")
    (empty,) = problems(write(tmp_path, ""))
    assert "empty mission file" in empty
    (listing,) = problems(write(tmp_path, "- 1\n- 2\n"))
    assert "mapping" in listing
    (missing,) = problems(tmp_path / "absent.yaml")
    assert "cannot read" in missing


def test_apply_overrides_revalidates_and_rederives(tmp_path):
    mission = load_mission(write(tmp_path, GOOD))
    changed = apply_overrides(
        mission, {"landing.verification_altitude": "5.0", "cruise_altitude": 60,
                  "waypoints.0.2": 45}
    )
    assert changed.landing.verification_altitude == 5.0
    assert changed.lsm.verification_altitude == 5.0
    assert changed.weights.normaliser == 60.0
    assert changed.waypoints_enu()[0] == (10.0, 0.0, 45.0)
    assert mission.landing.verification_altitude == 2.5  # the original is untouched
    again = apply_overrides(changed, {"seed": 9})
    assert again.seed == 9 and again.cruise_altitude == 60.0


@pytest.mark.parametrize("key", ["landing.nope", "nope", "nope.deeper", "waypoints.7.0",
                                 "seed.x"])
def test_apply_overrides_unknown_key_names_it(tmp_path, key):
    mission = load_mission(write(tmp_path, GOOD))
    with pytest.raises(UserError, match=key.split(".")[0]):
        apply_overrides(mission, {key: 1})


def test_apply_overrides_bad_value_names_the_key(tmp_path):
    mission = load_mission(write(tmp_path, GOOD))
    with pytest.raises(UserError, match="landing.verification_altitude"):
        apply_overrides(mission, {"landing.verification_altitude": -2})


def test_mission_built_in_python_gets_the_same_defaults():
    mission = Mission(waypoints=[(0, 10, 20)], cruise_altitude=20)
    assert mission.weights.normaliser == 20.0
    assert apply_overrides(mission, {"cruise_altitude": 30}).weights.normaliser == 30.0


def test_signing_key_hex_passphrase_and_environment(tmp_path, monkeypatch):
    hex_key = "ab" * 32
    mission = Mission(waypoints=[(0, 10, 20)], vehicle={"signing_key": hex_key})
    assert mission.vehicle.signing_key_bytes() == bytes.fromhex(hex_key)
    phrase = Mission(waypoints=[(0, 10, 20)], vehicle={"signing_key": "secret"})
    assert len(phrase.vehicle.signing_key_bytes()) == 32
    monkeypatch.delenv("LANDER_TEST_KEY", raising=False)
    with pytest.raises(ValidationError, match="environment variable LANDER_TEST_KEY is not set"):
        Mission(waypoints=[(0, 10, 20)], vehicle={"signing_key_env": "LANDER_TEST_KEY"})
    monkeypatch.setenv("LANDER_TEST_KEY", hex_key)
    env = Mission(waypoints=[(0, 10, 20)], vehicle={"signing_key_env": "LANDER_TEST_KEY"})
    assert env.vehicle.signing_key_bytes() == bytes.fromhex(hex_key)
    monkeypatch.delenv("LANDER_TEST_KEY")  # gone between validation and flight
    with pytest.raises(UserError, match="LANDER_TEST_KEY"):
        env.vehicle.signing_key_bytes()
    assert Mission(waypoints=[(0, 10, 20)]).vehicle.signing_key_bytes() is None


@pytest.mark.parametrize("name", ["demo.yaml", "mars_demo.yaml", "mars_science.yaml"])
def test_shipped_missions_validate(name):
    path = REPO / "missions" / name
    if not path.exists():
        pytest.skip(f"{name} not written yet")
    mission = load_mission(path)
    assert mission.vehicle.connection == "sim://"


def test_file_world_path_is_relative_to_the_mission_file(tmp_path):
    import numpy as np

    (tmp_path / "maps").mkdir()
    # 400 m: the route and its search patterns stay on the model
    np.save(tmp_path / "maps" / "dem.npy", np.zeros((401, 401), dtype=np.float32))
    path = write(tmp_path, GOOD + "world: {kind: file, path: maps/dem.npy, "
                 "source_cell_size: 1.0}\n")
    mission = load_mission(path)
    assert Path(mission.world.path) == tmp_path / "maps" / "dem.npy"


def test_model_level_checks_point_at_the_field_they_name(tmp_path):
    rate = write(tmp_path, GOOD + "tick_rate: 5\nperception:\n  detector: scripted\n"
                 "  rate: 10\n")
    (message,) = problems(rate)
    assert message.startswith(f"{rate}:9: perception.rate: 10.0 Hz is faster than tick_rate")
    low = write(tmp_path, GOOD + "tick_rate: 5\nperception:\n  detector: scripted\n"
                "  low_altitude_rate: 10\n", "low.yaml")
    (message,) = problems(low)
    assert "perception.low_altitude_rate: 10.0 Hz is faster than tick_rate" in message
    rectangle = write(tmp_path, GOOD + "landing:\n  search_rectangle: [0, 3]\n")
    (message,) = problems(rectangle)
    assert message.startswith(f"{rectangle}:7: landing.search_rectangle.0: must be > 0")


def test_unnamed_mission_takes_the_file_name(tmp_path):
    assert load_mission(write(tmp_path, GOOD.replace("name: t\n", ""), "survey.yaml")).name \
        == "survey"
    assert load_mission(write(tmp_path, GOOD)).name == "t"


def _numbers_in_schema(node, defs, path=(), description=None):
    """(dotted path, schema node, description) of every number the mission schema holds."""
    while "$ref" in node:
        node = defs[node["$ref"].rsplit("/", 1)[-1]]
    description = node.get("description", description)
    for union in ("anyOf", "oneOf"):
        for option in node.get(union, ()):
            yield from _numbers_in_schema(option, defs, path, description)
    kind = node.get("type")
    if kind == "object":
        for key, child in node.get("properties", {}).items():
            yield from _numbers_in_schema(child, defs, (*path, key))
        if isinstance(node.get("additionalProperties"), dict):
            yield from _numbers_in_schema(node["additionalProperties"], defs, (*path, "*"),
                                          description)
    elif kind == "array":
        for i, child in enumerate(node.get("prefixItems", ())):
            yield from _numbers_in_schema(child, defs, (*path, i), description)
        if "items" in node:
            yield from _numbers_in_schema(node["items"], defs, (*path, "[]"), description)
    elif kind in ("number", "integer"):
        yield ".".join(map(str, path)), node, description


def test_every_number_in_the_schema_is_bounded_and_described():
    schema = Mission.model_json_schema()
    numbers = list(_numbers_in_schema(schema, schema["$defs"]))
    assert len(numbers) > 200  # every section is walked
    unbounded = [
        path for path, node, _ in numbers
        if not ({"minimum", "exclusiveMinimum"} & node.keys()
                and {"maximum", "exclusiveMaximum"} & node.keys())
    ]
    undescribed = [path for path, _, description in numbers if not description]
    assert unbounded == [] and undescribed == []


def test_lidar_coverage_rule_is_off_in_flight_unless_the_mission_sets_it(tmp_path):
    # A verification hover's cloud seldom shows a site's whole clearance ring: with the rule
    # on, clear sites would be banned (docs/lidar-and-elevation-models.md); lander detect
    # keeps the settings' default.
    from lsd.lidar_pca.settings import LidarPcaSettings

    assert LidarPcaSettings().max_gap == 2.5
    for given, expected in [("", None), ("perception: {lidar_pca: {min_spread: 0.3}}\n", None),
                            ("perception: {lidar_pca: {max_gap: 3}}\n", 3.0)]:
        mission = load_mission(write(tmp_path, GOOD + given))
        assert mission.perception.lidar_pca.max_gap == expected
