import re

import numpy as np
import pytest

from autonomy.campaign import (
    newcombe_interval,
    newcombe_paired_interval,
    parse_vary,
    run_seed,
    variants,
    wilson_interval,
)
from autonomy.errors import UserError


def test_wilson_interval_matches_published_values():
    assert wilson_interval(8, 10) == pytest.approx((0.4902, 0.9433), abs=5e-4)
    low, high = wilson_interval(0, 10)
    assert low == 0.0 and high == pytest.approx(0.2775, abs=5e-4)


def test_wilson_interval_of_no_runs_is_undefined():
    assert all(np.isnan(wilson_interval(0, 0)))


def test_newcombe_independent_matches_newcombe_1998_example():
    # Newcombe (1998) Stat Med 17:873, 56/70 - 48/80, method 10.
    assert newcombe_interval(56, 70, 48, 80) == pytest.approx((0.0524, 0.3339), abs=5e-4)


def test_newcombe_paired_matches_published_example():
    # Paired 2x2 table [[59, 6], [16, 80]] (Fagerland et al., Statistical analysis of
    # contingency tables, ch. 8): estimate -0.0621, 95 % CI -0.1186 to -0.0046.
    assert newcombe_paired_interval(59, 6, 16, 80) == pytest.approx(
        (-0.1186, -0.0046), abs=5e-4
    )


def test_paired_interval_is_narrower_than_independent_for_correlated_runs():
    paired = newcombe_paired_interval(40, 5, 2, 13)
    independent = newcombe_interval(45, 60, 42, 60)
    assert paired[1] - paired[0] < independent[1] - independent[0]


@pytest.mark.parametrize(
    ("option", "key", "values"),
    [
        ("landing.verification_altitude=2.5,5,10", "landing.verification_altitude",
         (2.5, 5, 10)),
        ("sitl.wind.speed=0:8", "sitl.wind.speed", tuple(range(9))),
        ("sitl.wind.speed=0:8:5", "sitl.wind.speed", (0, 2, 4, 6, 8)),
        ("weights.size=0:1:3", "weights.size", (0.0, 0.5, 1.0)),
        ("world.kind=mars,flat", "world.kind", ("mars", "flat")),
        ("landing.enabled=true", "landing.enabled", (True,)),
        ("a.b=-2:2:3", "a.b", (-2, 0, 2)),
        ("landing.search_rectangle=[40,30],[80,60]", "landing.search_rectangle",
         ([40, 30], [80, 60])),
        ("world.path='C:/a.npy',b.npy", "world.path", ("C:/a.npy", "b.npy")),
        ("weights.size=1e-1,2", "weights.size", (0.1, 2)),
    ],
)
def test_spec_grammar(option, key, values):
    vary = parse_vary(option)
    assert vary.key == key
    assert vary.values == values
    assert [type(v) for v in vary.values] == [type(v) for v in values]


@pytest.mark.parametrize(
    "option",
    ["landing.verification_altitude", "=1,2", "a b=1", "x=", "x=1,,2", "x=8:0", "x=0:8:1",
     "x=0:8:two", "x=a:b", "x=0.5:2", "x=1:2:3:4", "x=1,1", "x=nan:1:3", "x=[1,2",
     "x={a: 1}"],
)
def test_malformed_specs_are_user_errors(option):
    with pytest.raises(UserError):
        parse_vary(option)


def test_variants_are_the_cartesian_product_in_option_order():
    chosen = variants([parse_vary("a=1,2"), parse_vary("b=x,y,z")])
    assert [v.overrides for v in chosen][:4] == [
        {"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 1, "b": "z"}, {"a": 2, "b": "x"}]
    assert len(chosen) == 6
    assert len({v.key for v in chosen}) == 6
    assert [v.index for v in chosen] == list(range(6))


def test_a_key_varied_twice_is_a_user_error():
    with pytest.raises(UserError, match="more than once"):
        variants([parse_vary("a=1,2"), parse_vary("a=3")])


def test_run_seeds_are_spawned_children_of_the_campaign_seed():
    children = np.random.SeedSequence(42).spawn(5)
    expected = [int(c.generate_state(1)[0]) for c in children]
    assert [run_seed(42, i) for i in range(5)] == expected
    assert run_seed(43, 0) != run_seed(42, 0)


def record(outcome, seed, time_to_land=None, safe=None):
    return {"outcome": outcome, "seed": seed, "time_to_land": time_to_land,
            "touchdown_safe": safe, "variant_key": ""}


def test_summary_counts_outcomes_and_leaves_errors_out_of_the_success_rate():
    from autonomy.campaign import format_table, summarise

    runs = ([record("landed", i, 100.0 + i, True) for i in range(8)]
            + [record("landed", 8, 50.0, False), record("error", 9)])
    row = summarise(runs)
    assert (row["runs"], row["landed"], row["landed_unsafe"], row["error"]) == (10, 8, 1, 1)
    assert row["success_rate"] == pytest.approx(8 / 9)
    assert (row["success_low"], row["success_high"]) == pytest.approx(wilson_interval(8, 9))
    times = [100.0 + i for i in range(8)] + [50.0]
    assert row["time_to_land_median"] == pytest.approx(np.median(times))
    assert row["time_to_land_p90"] == pytest.approx(np.percentile(times, 90))
    table = format_table([row]).splitlines()
    assert "success %" in table[0] and "88.9" in table[1]


def test_unsafe_touchdowns_count_landings_in_place_on_unsafe_ground_too():
    from autonomy.campaign import compare_missions, format_table, summarise

    runs = [record("landed", 0, 90.0, True), record("landed", 1, 90.0, False),
            record("no_site", 2, 300.0, False), record("no_site", 3, 300.0, True),
            record("crashed", 4)]
    row = summarise(runs)
    assert (row["landed_unsafe"], row["no_site"], row["unsafe_touchdowns"]) == (1, 2, 2)
    head, line = format_table([row]).splitlines()
    assert "unsafe touchdowns" in head
    assert compare_missions(["a", "b"], [runs, runs])[0]["unsafe"] == 2


def test_failsafe_landings_have_their_own_column_and_are_no_success():
    from autonomy.campaign import format_table, summarise

    runs = [record("landed", 0, 90.0, True), record("landed", 1, 95.0, True),
            record("failsafe", 2, 700.0, True), record("failsafe", 3, 710.0, False),
            record("no_site", 4, 650.0, True)]
    row = summarise(runs)
    assert (row["landed"], row["failsafe"], row["no_site"]) == (2, 2, 1)
    assert row["success_rate"] == pytest.approx(2 / 5)
    assert (row["success_low"], row["success_high"]) == pytest.approx(wilson_interval(2, 5))
    assert row["unsafe_touchdowns"] == 1  # the failsafe landing on unsafe ground
    assert row["time_to_land_median"] == pytest.approx(92.5)  # landed runs only
    head, line = format_table([row]).splitlines()
    columns = [c.strip() for c in head.split("  ") if c.strip()]  # 2+ blanks between
    assert columns.index("failsafe landing") == columns.index("no site") + 1
    assert line.split()[columns.index("failsafe landing")] == "2"


def test_comparison_pairs_runs_by_seed():
    from autonomy.campaign import compare_missions

    base = [record("landed", s, 80.0, True) for s in range(6)] + [record("crashed", 6)]
    other = ([record("landed", s, 80.0, True) for s in range(3)]
             + [record("no_site", s) for s in range(3, 6)] + [record("error", 6)])
    first, second = compare_missions(["a", "b"], [base, other])
    assert first["difference"] == 0.0 and first["pairs"] == 7
    assert second["pairs"] == 6  # the errored seed is left out
    assert (second["both"], second["only_baseline"]) == (3, 3)
    assert second["difference"] == pytest.approx(-0.5)
    assert (second["difference_low"], second["difference_high"]) == pytest.approx(
        newcombe_paired_interval(3, 0, 3, 0))


def test_progress_rewrites_one_line_on_a_terminal():
    import io

    from autonomy.campaign.progress import Progress

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    stream = Terminal()
    progress = Progress(3, stream)
    for outcome in ("landed", "error", "crashed"):
        progress.update(record(outcome, 0, 90.0, True))
    text = stream.getvalue()
    assert text.count("\r") == 3 and text.endswith("\n") and text.count("\n") == 1
    assert "3/3 runs, success 50.0%" in text and "1 error" in text


def test_collisions_are_summed_over_all_runs_and_have_their_column():
    from autonomy.campaign import format_table, summarise

    runs = [record("landed", 0, 90.0, True), {**record("landed", 1, 90.0, False), "collisions": 2},
            {**record("crashed", 2), "collisions": 1}, {**record("error", 3), "collisions": None}]
    row = summarise(runs)
    assert row["collisions"] == 3
    head, line = (re.split(r"\s{2,}", text.strip()) for text in format_table([row]).splitlines())
    assert line[head.index("collisions")] == "3"
