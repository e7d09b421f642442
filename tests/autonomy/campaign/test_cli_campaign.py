"""``lander campaign`` end to end with the real runner on missions/demo.yaml (few runs)."""

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from autonomy.campaign import NONDETERMINISTIC_FIELDS
from autonomy.cli import main

DEMO = Path(__file__).resolve().parents[3] / "missions" / "demo.yaml"


def records(out):
    lines = (out / "runs.jsonl").read_text().splitlines()
    found = [json.loads(line) for line in lines]
    for r in found:
        for field in NONDETERMINISTIC_FIELDS:
            r.pop(field)
    return sorted(found, key=lambda r: r["run_id"])


def lander(*args):
    return main(["campaign", *map(str, args)])


def test_pool_and_dask_fly_the_same_runs_and_rerun_skips_them(tmp_path, capsys):
    distributed = pytest.importorskip("distributed")
    assert lander(DEMO, "--runs", 2, "--seed", 3, "--workers", 2, "--out", tmp_path / "pool",
                  "--quiet") == 0
    table = capsys.readouterr().out
    assert "landed safe" in table and "flew 2 run(s), 0 already recorded" in table
    pool = records(tmp_path / "pool")
    assert [r["run_id"] for r in pool] == ["v000-r00000", "v000-r00001"]
    assert all(r["outcome"] == "landed" and r["touchdown_safe"] for r in pool)
    assert all(r["time_to_land"] > 0 and r["energy"] > 0 for r in pool)
    assert pool[0]["seed"] != pool[1]["seed"]
    for name in ("summary.json", "campaign.png"):
        assert (tmp_path / "pool" / name).stat().st_size > 0

    assert lander(DEMO, "--runs", 2, "--seed", 3, "--out", tmp_path / "pool", "--quiet") == 0
    assert "flew 0 run(s), 2 already recorded" in capsys.readouterr().out
    assert len((tmp_path / "pool" / "runs.jsonl").read_text().splitlines()) == 2

    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  protocol="tcp", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert lander(DEMO, "--runs", 2, "--seed", 3, "--scheduler", cluster.scheduler_address,
                      "--out", tmp_path / "dask", "--quiet") == 0
    assert records(tmp_path / "dask") == pool


def test_a_variant_with_a_corrupt_world_file_is_refused_before_any_flight(tmp_path, capsys):
    # The schema reads a file world when it validates it, so the bad variant is refused up
    # front (a flight that raises anyway is recorded as error: see test_engine.py).
    good, bad = tmp_path / "flat.npy", tmp_path / "corrupt.npy"
    np.save(good, np.zeros((301, 301), dtype=np.float32))  # the demo's route stays on it
    bad.write_bytes(b"this is not an elevation model")
    mission = yaml.safe_load(DEMO.read_text())
    mission["world"] = {"kind": "file", "path": str(good), "source_cell_size": 1.0}
    path = tmp_path / "file_world.yaml"
    path.write_text(yaml.safe_dump(mission))
    assert lander(path, "--runs", 1, "--vary", f"world.path={bad},{good}", "--workers", 2,
                  "--out", tmp_path / "out", "--quiet") == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("lander campaign: error: --vary: override world.path: cannot read ")
    assert "corrupt.npy" in line
    assert not (tmp_path / "out" / "runs.jsonl").exists()


def test_compare_flies_the_same_seeds_through_each_mission(tmp_path, capsys):
    mission = yaml.safe_load(DEMO.read_text())
    mission["landing"]["verification_altitude"] = 5.0
    other = tmp_path / "high_verification.yaml"
    other.write_text(yaml.safe_dump(mission))
    assert lander("--compare", DEMO, other, "--runs", 1, "--workers", 2,
                  "--out", tmp_path, "--quiet") == 0
    out = capsys.readouterr().out
    assert "diff vs demo" in out
    compared = json.loads((tmp_path / "compare.json").read_text())
    base, high = compared["missions"]
    assert (base["mission"], high["mission"]) == ("demo", "high_verification")
    assert base["pairs"] == high["pairs"] == 1
    assert [r["seed"] for r in records(tmp_path / "demo")] == [
        r["seed"] for r in records(tmp_path / "high_verification")]
    assert base["difference"] == 0.0
    assert high["difference_low"] <= high["difference"] <= high["difference_high"]
    assert {"unsafe", "success_low", "success_high"} <= set(high)


@pytest.mark.parametrize(
    ("vary", "message"),
    [
        ("landing.no_such_setting=1,2", "landing.no_such_setting"),
        ("landing.verification_altitude=5:1", "runs backwards"),
        ("landing.verification_altitude=1:5:x", "count N"),
        ("landing.verification_altitude=-1,2", "landing.verification_altitude"),
        ("no_equals_sign", "KEY=SPEC"),
    ],
)
def test_bad_vary_exits_2_with_one_line_before_any_run(tmp_path, capsys, vary, message):
    assert lander(DEMO, "--runs", 1, "--vary", vary, "--out", tmp_path) == 2
    err = capsys.readouterr().err
    assert message in err and len(err.strip().splitlines()) == 1
    assert err.startswith("lander campaign: error:")
    assert not (tmp_path / "runs.jsonl").exists()


def test_unreachable_scheduler_exits_2_before_any_run(tmp_path, capsys):
    pytest.importorskip("distributed")
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    assert lander(DEMO, "--runs", 1, "--scheduler", f"tcp://127.0.0.1:{port}",
                  "--connect-timeout", 1, "--out", tmp_path) == 2
    assert "cannot reach the scheduler" in capsys.readouterr().err
    assert not (tmp_path / "runs.jsonl").exists()


@pytest.mark.parametrize(
    "args",
    [["--runs", "0", DEMO], ["--runs", "1"], ["--runs", "1", "--compare", DEMO],
     ["--runs", "1", "--workers", "0", DEMO], ["--runs", "1", DEMO, "--compare", DEMO, DEMO]],
)
def test_bad_options_exit_2(tmp_path, args, capsys):
    assert lander(*args, "--out", tmp_path) == 2
    assert "lander campaign: error:" in capsys.readouterr().err


def test_the_mission_fingerprint_follows_the_file_not_the_schema_defaults():
    from autonomy.campaign.plan import mission_digest
    from autonomy.config import apply_overrides, load_mission, parse_mission

    text = DEMO.read_text()
    demo = load_mission(DEMO)
    assert mission_digest(demo) == mission_digest(parse_mission(text + "\n# a comment\n"))
    changed = apply_overrides(demo, {"landing.verification_altitude": 5.0})
    assert mission_digest(changed) != mission_digest(demo)


def _children(pid):
    """Pids of the processes whose parent is ``pid``, with their command lines."""
    found = {}
    for entry in Path("/proc").iterdir():
        try:
            if int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1]) == pid:
                found[int(entry.name)] = (entry / "cmdline").read_bytes()
        except (OSError, ValueError, IndexError):
            continue
    return found


def _lander_while(command: list[str], env: dict, meddle) -> tuple[int, str, str]:
    """Run ``command`` (lander) and call ``meddle(its pid)`` every 10 ms while it runs,
    until ``meddle`` returns True or lander ends; (exit code, stdout, stderr)."""
    lander_process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                      text=True, env=env)
    try:
        while lander_process.poll() is None and not meddle(lander_process.pid):
            time.sleep(0.01)
        stdout, stderr = lander_process.communicate(timeout=100)
    finally:
        if lander_process.poll() is None:
            lander_process.kill()
            lander_process.wait()
    return lander_process.returncode, stdout, stderr


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_a_run_whose_worker_is_killed_fails_by_name_and_the_same_command_flies_it(tmp_path):
    # As the OOM killer would: every worker process lander's fork server starts is killed
    # (SIGKILL), whether it is starting or flying, until lander ends.
    out = tmp_path / "campaign"
    command = [sys.executable, "-m", "autonomy", "campaign", str(DEMO), "--runs", "1",
               "--workers", "1", "--no-pages", "--quiet", "--out", str(out)]
    env = {**os.environ, "PYTHONPATH": str(DEMO.parents[1])}

    def kill_workers(lander_pid: int) -> bool:
        for server, cmdline in _children(lander_pid).items():
            if b"forkserver" in cmdline:
                for worker in _children(server):
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(worker, signal.SIGKILL)
        return False  # until lander ends

    returncode, stdout, stderr = _lander_while(command, env, kill_workers)
    assert returncode == 1, stderr
    assert "Traceback" not in stderr, stderr
    seed = json.loads((out / "runs.jsonl").read_text())["seed"]
    assert stderr.strip().splitlines()[-1] == (
        f"run v000-r00000 (seed {seed}) failed: its worker process died while flying this "
        "run, twice (the second time alone): killed by SIGKILL (possibly out of memory: the "
        "kernel's OOM killer sends SIGKILL); the same command flies it again")
    assert "flew 1 run(s), 0 already recorded; 1 run(s) raised" in stdout
    (record,) = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert (record["outcome"], record["worker_died"]) == ("error", "SIGKILL")

    # Undisturbed, the same command flies that run again (and only it), and exits 0.
    again = subprocess.run(command, capture_output=True, text=True, env=env, timeout=100)
    assert again.returncode == 0, again.stderr
    assert "flew 1 run(s), 0 already recorded" in again.stdout
    latest = json.loads((out / "runs.jsonl").read_text().splitlines()[-1])
    assert latest["outcome"] == "landed" and "worker_died" not in latest


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
def test_a_campaign_whose_fork_server_is_killed_while_it_starts_flies_on(tmp_path):
    # The fork server dies (the OOM killer, a Ctrl-C meant for it) while lander starts a
    # worker from it: lander starts it again instead of failing with an internal error.
    out = tmp_path / "campaign"
    killed = []

    def kill_the_server_before_a_worker(lander_pid: int) -> bool:
        for server, cmdline in _children(lander_pid).items():
            if b"forkserver" in cmdline and not _children(server):  # no worker yet
                os.kill(server, signal.SIGKILL)
                killed.append(server)
        return bool(killed)

    returncode, stdout, stderr = _lander_while(
        [sys.executable, "-m", "autonomy", "campaign", str(DEMO), "--runs", "1", "--workers",
         "1", "--no-pages", "--quiet", "--out", str(out)],
        {**os.environ, "PYTHONPATH": str(DEMO.parents[1])}, kill_the_server_before_a_worker)
    assert killed
    assert returncode == 0, stderr
    assert "flew 1 run(s), 0 already recorded" in stdout
    (record,) = [json.loads(line) for line in (out / "runs.jsonl").read_text().splitlines()]
    assert record["outcome"] == "landed"
