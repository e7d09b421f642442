"""No traceback on any input: every entry point, fed generated and mutated input, ends with
exit 0, 1 or 2, one clear line per problem, and within its deadline (harness.py says how).

The example counts (derandomized: CI tries the same cases each run) keep this module to
about half a minute; benchmarks/bench_fuzz.py runs the same strategies over 10,000 and more
inputs, drawn afresh from a seed.
"""

from __future__ import annotations

import harness
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

FAST = settings(max_examples=40, deadline=None, derandomize=True, database=None,
                suppress_health_check=list(HealthCheck))
SLOW = settings(FAST, max_examples=4)


def check(fuzz, case: harness.Case) -> harness.Result:
    runner, files, _ = fuzz
    result = harness.run_case(runner, files, case)
    assert not result.problems(), result.describe()
    return result


@settings(FAST, max_examples=25)
@given(data=st.data())
def test_schema_generated_missions_validate_or_are_refused_clearly(fuzz, data):
    check(fuzz, data.draw(harness.validate_cases(fuzz[1], "schema")))


@FAST
@given(data=st.data())
def test_mutated_missions_validate_or_are_refused_clearly(fuzz, data):
    check(fuzz, data.draw(harness.validate_cases(fuzz[1], "mutated")))


@SLOW
@given(data=st.data())
def test_mutated_missions_fly_or_are_refused_clearly(fuzz, data):
    check(fuzz, data.draw(harness.fly_cases(fuzz[1])))


@settings(FAST, max_examples=40)
@given(data=st.data())
def test_argument_lists_of_the_quick_commands(fuzz, data):
    command = data.draw(st.sampled_from(["validate", "tree", "sitl", "link", "detect", "replay"]))
    check(fuzz, data.draw(harness.cli_cases(fuzz[1], fuzz[2], command)))


@settings(FAST, max_examples=6)
@given(data=st.data())
def test_argument_lists_of_the_flying_commands(fuzz, data):
    command = data.draw(st.sampled_from(["fly", "campaign", "terrain", "demo"]))
    check(fuzz, data.draw(harness.cli_cases(fuzz[1], fuzz[2], command)))


@settings(FAST, max_examples=40)
@given(data=st.data())
def test_corrupt_detector_inputs(fuzz, data):
    check(fuzz, data.draw(harness.detect_cases(fuzz[1])))


@settings(FAST, max_examples=25)
@given(data=st.data())
def test_corrupt_world_files(fuzz, data):
    check(fuzz, data.draw(harness.world_file_cases(fuzz[1])))
