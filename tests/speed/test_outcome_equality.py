"""The speed work changes no outcome (issue 21): flights flown now are the flights recorded
before it, bit for bit (tests/speed/data, recorded with the code before the optimisations;
tests/speed/golden.py flies every recorded seed, this test a short subset)."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


def _module(name: str):
    if name not in sys.modules:
        spec = importlib.util.spec_from_file_location(name, HERE / f"{name.split('_', 1)[1]}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        spec.loader.exec_module(module)
    return sys.modules[name]


@pytest.fixture
def golden():
    """The recordings' module; skips when the numerical libraries are not the ones the
    recordings were made with (their last bits differ between versions: record again with
    ``python tests/speed/golden.py --write`` and ``python tests/speed/frames.py --write``
    on the code before a speed change, then compare)."""
    module = _module("speed_golden")
    if module.libraries() != module.recorded_with():
        pytest.skip(f"recorded with {module.recorded_with()}, running {module.libraries()}")
    return module


@pytest.mark.parametrize(("mission_file", "seed"), [("demo.yaml", 0), ("mars_science.yaml", 1)])
def test_flight_outcome_is_the_recorded_one(golden, mission_file, seed):
    expected = golden.load()[golden.key(mission_file, seed)]
    got = golden.fly_record(mission_file, seed)
    assert golden.differences(expected, got) == []


def test_perception_frames_are_the_recorded_ones(golden):
    frames = _module("speed_frames")
    expected = json.loads(frames.DATA.read_text())
    got = frames.frame_digests()
    assert len(got) == len(expected)
    for a, b in zip(expected, got, strict=True):
        assert json.dumps(b) == json.dumps(a), f"frame at t={a['t']} differs"
