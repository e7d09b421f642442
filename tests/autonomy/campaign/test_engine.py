"""The campaign machinery (pool, Dask, resume, errors, outputs) with stand-in flights."""

import json
import socket
import sys

import pytest

from autonomy.campaign import NONDETERMINISTIC_FIELDS, LocalPool, run_campaign
from autonomy.errors import UserError


def lines_without_wall_time(path):
    records = [json.loads(line) for line in path.read_text().splitlines()]
    for r in records:
        for field in NONDETERMINISTIC_FIELDS:
            r.pop(field, None)
    return sorted(json.dumps(r, sort_keys=True) for r in records)


def campaign(fakes, out, mission=None, **kwargs):
    kwargs.setdefault("runs", 4)
    kwargs.setdefault("seed", 5)
    kwargs.setdefault("quiet", True)
    return run_campaign(mission or fakes.FakeMission(), out_dir=out, flight=fakes.fly,
                        apply_overrides=fakes.apply, **kwargs)


def test_local_pool_runs_are_reproducible_and_complete(fakes, tmp_path):
    first = campaign(fakes, tmp_path / "a", vary=["success_rate=0.2,0.9"], workers=2)
    campaign(fakes, tmp_path / "b", vary=["success_rate=0.2,0.9"], workers=1)
    assert lines_without_wall_time(tmp_path / "a" / "runs.jsonl") == lines_without_wall_time(
        tmp_path / "b" / "runs.jsonl")
    assert first.flown == 8
    assert [r["run_id"] for r in first.records] == [
        f"v{v:03d}-r{i:05d}" for v in range(2) for i in range(4)]
    # Run i of every variant flies the same seed.
    assert [r["seed"] for r in first.records[:4]] == [r["seed"] for r in first.records[4:]]
    assert len({r["seed"] for r in first.records}) == 4
    # Each record keeps why its landing phase ended, so outcomes can be re-derived later.
    assert all(r["outcome_hint"] == ("no_site" if r["outcome"] == "no_site" else None)
               for r in first.records)
    assert any(r["outcome"] == "no_site" for r in first.records)
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert [row["runs"] for row in summary["variants"]] == [4, 4]
    assert summary["variants"][0]["values"] == {"success_rate": 0.2}
    assert (tmp_path / "a" / "campaign.png").stat().st_size > 0


def test_throughput_counts_the_simulated_time_of_the_runs_flown_now(fakes, tmp_path):
    first = campaign(fakes, tmp_path, runs=3, backend=LocalPool(2))
    t = json.loads((tmp_path / "summary.json").read_text())["throughput"]
    assert t["runs"] == 3 and t["simulated_s"] == 3 * 250.0  # the fake flights' mission_time
    assert t["workers"] == 2
    assert t["flight_h_per_wall_h"] == pytest.approx(750.0 / t["wall_s"], rel=0.05)
    assert t["flight_h_per_wall_h_per_worker"] == pytest.approx(t["flight_h_per_wall_h"] / 2,
                                                                rel=0.01)
    assert "flight-h per wall-h" in first.throughput_line()
    again = campaign(fakes, tmp_path, runs=3, backend=LocalPool(2))
    assert again.throughput_line() is None  # nothing flown, nothing measured


def test_rerunning_skips_recorded_runs_and_extends(fakes, tmp_path):
    campaign(fakes, tmp_path, runs=3, backend=LocalPool(1))
    again = campaign(fakes, tmp_path, runs=3, backend=LocalPool(1))
    assert again.flown == 0 and again.skipped == 3
    more = campaign(fakes, tmp_path, runs=5, backend=LocalPool(1))
    assert more.flown == 2 and more.skipped == 3
    lines = (tmp_path / "runs.jsonl").read_text().splitlines()
    assert len(lines) == 5
    assert sorted(json.loads(line)["seed_index"] for line in lines) == [0, 1, 2, 3, 4]


def test_runs_of_another_mission_in_the_output_directory_are_refused(fakes, tmp_path):
    campaign(fakes, tmp_path, runs=1, backend=LocalPool(1))
    with pytest.raises(UserError, match="different mission"):
        campaign(fakes, tmp_path, runs=1, mission=fakes.FakeMission(success_rate=0.1),
                 backend=LocalPool(1))


def test_a_failing_variant_is_recorded_as_error_and_the_campaign_goes_on(fakes, tmp_path):
    mission = fakes.FakeMission(raise_when_above=0.5)
    result = campaign(fakes, tmp_path, mission=mission, vary=["success_rate=0.3,0.8"],
                      runs=3, workers=2)
    ok, failing = result.rows
    assert failing["error"] == 3 and failing["success_rate"] is None
    assert ok["error"] == 0 and ok["runs"] == 3
    errors = [r for r in result.records if r["outcome"] == "error"]
    assert len(errors) == 3
    assert all("deliberate failure" in r["error"] for r in errors)


def test_errors_are_skipped_on_resume_unless_retried(fakes, tmp_path):
    failing = fakes.FakeMission(raise_when_above=0.5)
    campaign(fakes, tmp_path, mission=failing, runs=2, backend=LocalPool(1))
    assert campaign(fakes, tmp_path, mission=failing, runs=2, backend=LocalPool(1)).flown == 0
    retried = campaign(fakes, tmp_path, mission=failing, runs=2, backend=LocalPool(1),
                       retry_errors=True)
    assert retried.flown == 2


def test_a_dying_worker_loses_only_its_own_run(fakes, tmp_path):
    from autonomy.campaign import run_seed

    doomed = run_seed(5, 1)
    result = campaign(fakes, tmp_path, mission=fakes.FakeMission(die_on_seed=doomed),
                      runs=4, workers=2)
    outcomes = {r["seed_index"]: r["outcome"] for r in result.records}
    assert outcomes[1] == "error"
    assert "worker process died" in result.records[1]["error"]
    assert all(outcomes[i] != "error" for i in (0, 2, 3))
    assert len((tmp_path / "runs.jsonl").read_text().splitlines()) == 4


def test_progress_lines_show_the_running_success_rate(fakes, tmp_path):
    import io

    stream = io.StringIO()
    campaign(fakes, tmp_path, runs=3, backend=LocalPool(1), quiet=False, progress=stream)
    lines = stream.getvalue().splitlines()
    assert lines[-1].startswith("campaign: 3/3 runs")
    assert "success" in lines[-1] and "\r" not in stream.getvalue()


def test_bad_vary_key_is_refused_before_any_run(fakes, tmp_path):
    with pytest.raises(UserError, match="no_such_key"):
        campaign(fakes, tmp_path, vary=["no_such_key=1,2"])
    assert not (tmp_path / "runs.jsonl").exists()


def test_dask_local_cluster_gives_the_same_records_as_the_pool(fakes, tmp_path):
    distributed = pytest.importorskip("distributed")
    campaign(fakes, tmp_path / "pool", runs=3, backend=LocalPool(1))
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  protocol="tcp", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        result = campaign(fakes, tmp_path / "dask", runs=3,
                          scheduler=cluster.scheduler_address)
    assert result.flown == 3
    assert lines_without_wall_time(tmp_path / "pool" / "runs.jsonl") == (
        lines_without_wall_time(tmp_path / "dask" / "runs.jsonl"))


def test_unreachable_scheduler_is_a_user_error(fakes, tmp_path):
    pytest.importorskip("distributed")
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    with pytest.raises(UserError, match="cannot reach"):
        campaign(fakes, tmp_path, runs=1, scheduler=f"tcp://127.0.0.1:{port}",
                 connect_timeout=1)
    assert not (tmp_path / "runs.jsonl").exists()


def test_scheduler_without_distributed_installed_is_a_user_error(fakes, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    with pytest.raises(UserError, match=r"landing-autonomy\[cluster\]"):
        campaign(fakes, tmp_path, runs=1, scheduler="tcp://127.0.0.1:8786")


@pytest.mark.parametrize("address", ["127.0.0.1:8786", "tcp://"])
def test_malformed_scheduler_address_is_a_user_error(fakes, tmp_path, address):
    pytest.importorskip("distributed")
    with pytest.raises(UserError, match="expected tcp://HOST:PORT"):
        campaign(fakes, tmp_path, runs=1, scheduler=address)


def test_a_run_whose_worker_is_killed_is_named_with_its_signal_and_flown_again(fakes, tmp_path):
    from autonomy.campaign import run_seed

    undisturbed = campaign(fakes, tmp_path / "undisturbed", workers=2)
    killed = run_seed(5, 2)
    mission = fakes.FakeMission(kill_on_seed=killed)
    result = campaign(fakes, tmp_path / "killed", mission=mission, workers=2)
    (died,) = result.died()
    assert (died["run_id"], died["outcome"], died["worker_died"]) == (
        "v000-r00002", "error", "SIGKILL")
    assert "killed by SIGKILL (possibly out of memory" in died["error"]
    # Every other run is on disk, as an undisturbed campaign flew it (but for the mission
    # fingerprint: the missions differ in kill_on_seed).
    def others(path):
        records = [json.loads(line) for line in lines_without_wall_time(path / "runs.jsonl")]
        return [{**r, "mission": None} for r in records if r["seed_index"] != 2]

    assert others(tmp_path / "killed") == others(tmp_path / "undisturbed")
    assert [r["outcome"] for r in result.records] == [
        r["outcome"] if r["seed_index"] != 2 else "error" for r in undisturbed.records]
    # Re-running flies exactly the run that died, and nothing else.
    again = campaign(fakes, tmp_path / "killed", mission=mission, workers=2)
    assert (again.flown, again.skipped) == (1, 3)
    assert [r["run_id"] for r in again.died()] == ["v000-r00002"]


def test_a_run_whose_dask_workers_die_is_named_and_flown_again(fakes, tmp_path):
    # Dask restarts a killed worker and hands its runs to another, up to allowed-failures
    # times (0 here: the first death gives the run up), then raises KilledWorker for it.
    # (Every run the dead worker held counts as suspect, so the campaign has one run.)
    distributed = pytest.importorskip("distributed")
    import dask

    from autonomy.campaign import run_seed

    mission = fakes.FakeMission(kill_on_seed=run_seed(5, 0))
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                     host="127.0.0.1", dashboard_address=None) as cluster:
        result = campaign(fakes, tmp_path, mission=mission, runs=1,
                          scheduler=cluster.scheduler_address)
        (died,) = result.died()
        assert (died["outcome"], died["worker_died"]) == ("error", "KilledWorker")
        assert "died while flying this run on every Dask worker" in died["error"]
        again = campaign(fakes, tmp_path, mission=mission, runs=1,
                         scheduler=cluster.scheduler_address)
    assert (again.flown, again.skipped) == (1, 0), "flown again, not skipped as a result"
