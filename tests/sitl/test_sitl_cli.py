"""``lander sitl``: bad input is one clear line and exit 2; a short run exits 0."""

from __future__ import annotations

import signal
import socket
import subprocess
import sys

import pytest

from autonomy.cli import main


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--udp", "localhost"], "--udp"),
        (["--tcp", "127.0.0.1:port"], "--tcp"),
        (["--udp", "127.0.0.1:99999"], "--udp"),
        (["--home", "47.4,8.5"], "--home"),
        (["--home", "95,8.5,400"], "--home"),
        (["--speedup", "0"], "--speedup"),
    ],
)
def test_bad_input_exits_2_with_one_line(capsys, argv, words):
    assert main(["sitl", *argv, "--duration", "0.1"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert words in err


@pytest.mark.parametrize("kind", [socket.SOCK_STREAM, socket.SOCK_DGRAM])
def test_port_in_use_exits_2(capsys, kind):
    taken = socket.socket(socket.AF_INET, kind)
    try:
        taken.bind(("127.0.0.1", 0))
        if kind == socket.SOCK_STREAM:
            taken.listen(1)
        port = taken.getsockname()[1]
        flag = "--tcp" if kind == socket.SOCK_STREAM else "--udp"
        assert main(["sitl", flag, f"127.0.0.1:{port}", "--duration", "0.1"]) == 2
    finally:
        taken.close()
    err = capsys.readouterr().err
    assert f"127.0.0.1:{port}" in err and "in use" in err


def test_short_run_serves_and_exits_0(capsys):
    argv = ["sitl", "--udp", "127.0.0.1:0", "--tcp", "127.0.0.1:0", "--autopilot", "px4",
            "--speedup", "1000", "--duration", "2", "--home=-35.36,149.16,584"]
    assert main(argv) == 0
    out = capsys.readouterr().out
    assert "px4" in out and "-35.360000,149.160000" in out
    assert "stopped at t=2.0 s" in out


def test_ctrl_c_stops_cleanly():
    proc = subprocess.Popen(
        [sys.executable, "-m", "autonomy", "sitl", "--udp", "127.0.0.1:0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # A shell's background jobs ignore SIGINT; give the child the normal Ctrl-C handler.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        assert "Ctrl-C to stop" in proc.stdout.readline()
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0
    assert "SITL stopped" in out
    assert "Traceback" not in err
