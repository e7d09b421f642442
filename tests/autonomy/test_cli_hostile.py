"""What a careless or hostile user does to the command line, beyond the fuzz suite: outputs
pointed at inputs or at another command's results, a full disk, typos, tabs, a terminal that
cannot show a name. Each case goes through ``lander`` (autonomy.cli.main) and checks the one
line it prints and that nothing was lost."""

from __future__ import annotations

import errno
import io
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

from autonomy.cli import main
from autonomy.cli.demo import mission_path

REPO = Path(__file__).resolve().parents[2]
SCRIPTED = mission_path("demo.yaml")
SKIP_SEARCH = mission_path("skip_search.yaml")


def _error(capsys) -> str:
    (line,) = capsys.readouterr().err.strip().splitlines()
    return line


# -- outputs over inputs or over another command's results ---------------------------------


@pytest.mark.parametrize("flag", ["--dot", "--xml"])
def test_tree_never_writes_over_the_mission_file(tmp_path, capsys, flag):
    mission = tmp_path / "m.yaml"
    mission.write_text(SCRIPTED.read_text())
    before = mission.read_bytes()
    assert main(["tree", str(mission), flag, str(tmp_path / "." / "m.yaml")]) == 2
    assert f"{flag} " in (line := _error(capsys)) and "is the mission file" in line
    assert mission.read_bytes() == before


def test_tree_never_writes_over_the_mission_s_tree_file_or_its_other_output(tmp_path, capsys):
    mission = tmp_path / SKIP_SEARCH.name  # a copy: the repository's file stays safe
    mission.write_text(SKIP_SEARCH.read_text())
    tree_file = tmp_path / "skip_search.xml"
    tree_file.write_bytes(before := SKIP_SEARCH.with_suffix(".xml").read_bytes())
    assert "tree: skip_search.xml" in mission.read_text()
    assert main(["tree", str(mission), "--xml", str(tree_file)]) == 2
    assert "is the mission's tree file" in _error(capsys)
    assert tree_file.read_bytes() == before
    same = str(tmp_path / "t.out")
    assert main(["tree", str(SCRIPTED), "--xml", same, "--dot", same]) == 2
    assert "--dot" in (line := _error(capsys)) and "is the --xml output" in line


def _campaign_folder(folder: Path) -> None:
    folder.mkdir()
    (folder / "runs.jsonl").write_text('{"run_id": "r0", "mission": "x"}\n')
    (folder / "summary.json").write_text(json.dumps({"variants": []}))


def test_fly_refuses_a_campaign_folder_and_leaves_it_alone(tmp_path, capsys):
    out = tmp_path / "campaign"
    _campaign_folder(out)
    before = (out / "summary.json").read_text()
    assert main(["fly", str(SCRIPTED), "--out", str(out), "--quiet"]) == 2
    assert "holds a campaign (runs.jsonl)" in _error(capsys)
    assert (out / "summary.json").read_text() == before
    assert sorted(p.name for p in out.iterdir()) == ["runs.jsonl", "summary.json"]


def test_campaign_refuses_a_flight_report_folder(tmp_path, capsys):
    out = tmp_path / "flight"
    out.mkdir()
    summary = json.dumps({"mission": "demo", "outcome": "landed"})
    (out / "summary.json").write_text(summary)
    assert main(["campaign", str(SCRIPTED), "--runs", "1", "--out", str(out), "--quiet"]) == 2
    assert "holds a flight's report (summary.json)" in _error(capsys)
    assert (out / "summary.json").read_text() == summary
    assert not (out / "runs.jsonl").exists()


def test_fly_refuses_a_folder_with_report_files_of_its_own_and_a_file_as_out(tmp_path,
                                                                            capsys):
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "report.png").write_bytes(b"my picture")
    assert main(["fly", str(SCRIPTED), "--out", str(mine), "--quiet"]) == 2
    assert "holds report.png, not from a flight" in _error(capsys)
    assert (mine / "report.png").read_bytes() == b"my picture"
    assert main(["fly", str(SCRIPTED), "--out", str(SCRIPTED), "--quiet"]) == 2
    assert "exists and is not a folder" in _error(capsys)


def test_a_full_disk_is_one_line_naming_the_report_folder(tmp_path, capsys, monkeypatch):
    import autonomy.runner

    def full_disk(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")  # as a buffered close does

    monkeypatch.setattr(autonomy.runner, "fly", full_disk)
    out = tmp_path / "out"
    assert main(["fly", str(SCRIPTED), "--out", str(out), "--quiet"]) == 2
    line = _error(capsys)
    assert line.startswith(f"lander fly: error: {out}: cannot write the flight's report")
    assert "No space left on device" in line and "incomplete" in line


def test_replay_that_cannot_write_its_rebuilt_page_is_one_line(tmp_path, capsys, monkeypatch):
    import autonomy.report.rebuild

    (tmp_path / "events.jsonl").write_text('{"t": 0}\n')

    def refused(folder):
        raise PermissionError(errno.EACCES, "Permission denied", str(folder / "report.html"))

    monkeypatch.setattr(autonomy.report.rebuild, "rebuild_page", refused)
    assert main(["replay", str(tmp_path), "--print"]) == 2
    assert _error(capsys) == (f"lander replay: error: {tmp_path / 'report.html'}: "
                              "Permission denied")


def test_detect_removes_an_earlier_run_s_geojson_it_does_not_replace(tmp_path, capsys):
    cloud = tmp_path / "cloud.npy"
    x, y = np.meshgrid(np.arange(0, 10, 0.5), np.arange(0, 10, 0.5))
    np.save(cloud, np.c_[x.ravel(), y.ravel(), np.zeros(x.size)])
    out = tmp_path / "out"
    out.mkdir()
    (out / "sites.geojson").write_text('{"type": "FeatureCollection", "features": []}')
    assert main(["detect", "--lidar", str(cloud), "--out", str(out), "--quiet"]) == 0
    assert "removed" in capsys.readouterr().out
    assert sorted(p.name for p in out.iterdir()) == ["overlay.png", "sites.csv"]


# -- files that are not what they seem -------------------------------------------------


def test_detect_names_a_directory_and_an_empty_ply(tmp_path, capsys):
    assert main(["detect", "--lidar", str(tmp_path)]) == 2
    assert _error(capsys).endswith(f"{tmp_path}: a directory, not a file")
    ply = tmp_path / "empty.ply"
    ply.write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\n"
                   "property float y\nproperty float z\nend_header\n")
    assert main(["detect", "--lidar", str(ply), "--out", str(tmp_path / "o")]) == 2
    assert _error(capsys).endswith("the PLY file holds no points (element vertex 0)")


@pytest.mark.parametrize(("text", "line", "reason"), [
    ("ncols 3\nnrows 2\ncellsize abc\n1 2 3\n4 5 6\n", 3, "cellsize 'abc' is not a number"),
    ("ncols 3\nnrows 2\ncelsize 1\n1 2 3\n4 5 6\n", 3,
     "'celsize' is not an ESRI ASCII header key (ncols, nrows, xllcorner, yllcorner, "
     "xllcenter, yllcenter, cellsize, NODATA_value)"),
    ("ncols 3.5\nnrows 2\ncellsize 1\n1 2 3\n4 5 6\n", 1,
     "ncols 3.5 is not a whole number of cells"),
    ("ncols 3\nnrows 2\n1 2 3\n4 5 6\n", 3, "the header lacks cellsize before the values"),
    ("ncols 3\nnrows 2\ncellsize 1\n1 2 3\n4 5\n", 5, "2 values in the row, ncols says 3"),
    ("ncols 3\nnrows 2\ncellsize 1\n1 2 3\n4 x 6\n", 5,
     "value 2 of the row, 'x', is not a number"),
    ("ncols 3\nnrows 3\ncellsize 1\n1 2 3\n4 5 6\n", 5,
     "the file ends after 2 row(s) of values, fewer than nrows (3)"),
    ("ncols 3\nnrows 2\ncellsize 1\n1 2 3\n4 5 6\n7 8 9\n", 6,
     "more rows of values than nrows (2)"),
])
def test_a_malformed_esri_ascii_model_is_named_by_file_line_and_reason(tmp_path, capsys, text,
                                                                       line, reason):
    asc = tmp_path / "dem.asc"
    asc.write_text(text)
    mission = tmp_path / "m.yaml"
    mission.write_text(f"waypoints: [[1, 1, 30]]\nworld: {{kind: file, path: '{asc}'}}\n")
    for command in ("validate", "fly"):
        assert main([command, str(mission)]) == 2
        assert _error(capsys).endswith(f": world.path: {asc}:{line}: {reason}")


def test_esri_ascii_rows_wrapped_over_lines_are_read_as_gdal_reads_them(tmp_path, capsys):
    asc = tmp_path / "dem.asc"
    asc.write_text("ncols 3\nnrows 2\ncellsize 200\n1 2 3 4\n5 6\n")
    mission = tmp_path / "m.yaml"
    mission.write_text(f"waypoints: [[1, 1, 30]]\nworld: {{kind: file, path: '{asc}'}}\n")
    assert main(["validate", str(mission)]) == 0


def _npy_mission(tmp_path: Path, npy: Path) -> Path:
    mission = tmp_path / "m.yaml"
    mission.write_text(f"waypoints: [[1, 1, 30]]\nworld: {{kind: file, path: '{npy}', "
                       "source_cell_size: 1, cell_size: 2}\n")
    return mission


def test_a_huge_npy_model_is_refused_from_its_header_before_its_data_is_read(tmp_path, capsys):
    npy = tmp_path / "dem.npy"
    with npy.open("wb") as f:  # the header alone: reading the data would fail differently
        np.lib.format.write_array_header_1_0(
            f, {"descr": "<f8", "fortran_order": False, "shape": (8001, 8001)})
    assert main(["validate", str(_npy_mission(tmp_path, npy))]) == 2
    assert _error(capsys).endswith(f": world.path: {npy}: 8001 x 8001 cells, more than the "
                                   "64,000,000 a world may hold (memory): crop or coarsen it")


@pytest.mark.parametrize(("array", "reason"), [
    (np.array([[1, None], [2, 3]], dtype=object), "holds object values, not numbers"),
    (np.zeros((2, 2), dtype=complex), "holds complex128 values, not numbers"),
    (np.zeros((3, 3, 3)), "holds a 3-D array of shape (3, 3, 3); an elevation model is a 2-D "
     "grid of heights"),
])
def test_an_npy_model_of_no_grid_of_numbers_is_refused_in_one_line(tmp_path, capsys, array,
                                                                   reason):
    npy = tmp_path / "dem.npy"
    np.save(npy, array, allow_pickle=True)
    assert main(["validate", str(_npy_mission(tmp_path, npy))]) == 2
    assert _error(capsys).endswith(f": world.path: {npy}: {reason}")


def test_an_npz_archive_named_npy_is_not_an_npy_file(tmp_path, capsys):
    npy = tmp_path / "dem.npy"
    with npy.open("wb") as f:
        np.savez(f, heights=np.zeros((3, 3)))
    assert main(["validate", str(_npy_mission(tmp_path, npy))]) == 2
    assert _error(capsys).endswith(f": world.path: cannot read {npy}: not a NumPy .npy file")


# -- mission files and overrides --------------------------------------------------------


def test_a_misspelt_setting_is_refused_with_the_name_it_resembles(tmp_path, capsys):
    path = tmp_path / "typo.yaml"
    path.write_text("waypoints: [[10, 0, 30]]\ncruise_altitud: 30\n"
                    "landing: {verification_altitde: 3}\nworld: {kind: mars, rock_densty: 1}\n"
                    "zzz: 1\n")
    assert main(["validate", str(path)]) == 2
    assert capsys.readouterr().err.splitlines() == [
        f"lander validate: error: {path}:2: cruise_altitud: unknown setting; did you mean "
        "cruise_altitude?",
        f"lander validate: error: {path}:3: landing.verification_altitde: unknown setting; "
        "did you mean verification_altitude?",
        f"lander validate: error: {path}:4: world.rock_densty: unknown setting; did you mean "
        "rock_density?",
        f"lander validate: error: {path}:5: zzz: unknown setting",
    ]
    assert main(["fly", str(SCRIPTED), "--set", "landing.centring_radios=1"]) == 2
    assert _error(capsys).endswith("unknown setting; did you mean centring_radius?")


def test_a_misspelt_tree_node_is_refused_with_the_registered_name_it_resembles(tmp_path,
                                                                                capsys):
    tree = tmp_path / "t.xml"
    tree.write_text('<root BTCPP_format="4" main_tree_to_execute="T">\n'
                    '  <BehaviorTree ID="T">\n    <Sequence>\n      <Takeof/>\n'
                    '      <Action ID="NavigateToWaypont" waypoint="{waypoint_1}"/>\n'
                    '      <Selector><Land/></Selector>\n      <Fly/>\n    </Sequence>\n'
                    '  </BehaviorTree>\n</root>\n')
    mission = tmp_path / "m.yaml"
    mission.write_text("waypoints: [[0, 0, 20]]\ntree: t.xml\n")
    unknown = "unknown node (see `lander tree --xml` for the registered ones)"
    for command in (["validate", str(mission)], ["tree", str(mission)]):
        assert main(command) == 2
        assert [line.split(": error: ", 1)[1] for line in
                capsys.readouterr().err.splitlines()] == [
            f"{tree}:4: Takeof: {unknown}; did you mean Takeoff?",
            f"{tree}:5: NavigateToWaypont: {unknown}; did you mean NavigateToWaypoint?",
            f"{tree}:6: Selector: {unknown}; BehaviorTree.CPP calls it Fallback",
            f"{tree}:7: Fly: {unknown}",
        ]


def test_a_tab_in_the_indentation_is_named(tmp_path, capsys):
    path = tmp_path / "tab.yaml"
    path.write_text("name: t\nwaypoints:\n\t- [1, 2, 30]\n")
    assert main(["validate", str(path)]) == 2
    assert _error(capsys).endswith("(a tab: YAML indents with spaces only)")


# -- links ------------------------------------------------------------------------------


@pytest.mark.parametrize("argv", [
    ["link", "udpout:127.0.0.1:0", "--duration", "1"],
    ["sitl", "--udp-out", "127.0.0.1:0", "--duration", "1"],
])
def test_port_0_is_no_address_to_send_to(capsys, argv):
    assert main(argv) == 2
    assert "port 0 is not an address" in _error(capsys)


@pytest.mark.parametrize("argv", [
    ["link", "tcp:[::1]:5760", "--duration", "1"],
    ["link", "udp:[::1]:14550", "--duration", "1"],
    ["link", "udpout:::1:14550", "--duration", "1"],
    ["fly", str(SCRIPTED), "--connect", "tcp:[::1]:5760", "--quiet"],
])
def test_an_ipv6_link_is_refused_in_one_line_as_pymavlink_is_ipv4(capsys, argv):
    assert main(argv) == 2
    line = _error(capsys)
    assert "an IPv6 address; MAVLink network links are IPv4 only here (pymavlink)" in line
    assert f"e.g. {argv[-2 if argv[0] == 'fly' else 1].split(':')[0]}:127.0.0.1:" in line


@pytest.mark.parametrize(("flag", "address"), [
    ("--tcp", "[::1]:5760"), ("--udp", "::1:14550"), ("--udp-out", "[::1]:14550"),
])
def test_the_sitl_refuses_an_ipv6_address_it_would_not_serve(capsys, flag, address):
    # --udp-out [::1]:14550 "served" before, every datagram to it silently dropped
    assert main(["sitl", flag, address, "--duration", "1"]) == 2
    assert _error(capsys) == (f"lander sitl: error: {flag}: {address}: an IPv6 address; the "
                              "SITL serves IPv4 only, as lander and pymavlink connect: use an "
                              "IPv4 address such as 127.0.0.1 or 0.0.0.0")


def test_a_host_with_only_an_ipv6_address_is_named_as_such(capsys, monkeypatch):
    import socket

    real = socket.getaddrinfo

    def ipv6_only(host, port, family=0, *args, **kwargs):
        if host != "v6.example":
            return real(host, port, family, *args, **kwargs)
        if family == socket.AF_INET:
            raise socket.gaierror(socket.EAI_ADDRFAMILY, "no IPv4 address")
        return [(socket.AF_INET6, socket.SOCK_STREAM, 6, "", ("::1", port, 0, 0))]

    monkeypatch.setattr(socket, "getaddrinfo", ipv6_only)
    assert main(["link", "tcp:v6.example:5760", "--duration", "1"]) == 2
    assert _error(capsys).endswith("tcp:v6.example:5760: v6.example has no IPv4 address; "
                                   "MAVLink network links are IPv4 only here (pymavlink)")


# -- the terminal -----------------------------------------------------------------------


def _fork_server_of(pid: int) -> bool:
    """Whether process ``pid`` has started its multiprocessing fork server (a child)."""
    for entry in Path("/proc").iterdir():
        try:
            stat = (entry / "stat").read_text()
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                if b"forkserver" in (entry / "cmdline").read_bytes():
                    return True
        except (OSError, ValueError, IndexError):
            continue
    return False


def test_ctrl_c_while_lander_imports_its_commands_is_one_line(capsys, monkeypatch):
    import autonomy.cli

    def ctrl_c():  # as a Ctrl-C during the seconds it takes to import the commands
        raise KeyboardInterrupt

    monkeypatch.setattr(autonomy.cli, "build_parser", ctrl_c)
    assert main(["campaign", str(SCRIPTED), "--runs", "1"]) == 130
    assert _error(capsys) == "lander: interrupted"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="reads /proc")
@pytest.mark.parametrize("when", ["the fork server starts", "a worker waits for its next run"])
def test_ctrl_c_while_a_campaign_starts_its_workers_is_one_line_not_a_traceback(tmp_path,
                                                                                when):
    # A terminal's Ctrl-C reaches lander, its fork server (seconds importing the flight
    # stack) and its workers (idle between runs): whenever it lands, lander says what is kept
    # and exits 130, and no other process prints a traceback.
    out = tmp_path / "campaign"
    process = subprocess.Popen(
        [sys.executable, "-m", "autonomy", "campaign", str(SCRIPTED), "--runs", "3",
         "--workers", "2", "--no-pages", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
        env={**os.environ, "PYTHONPATH": str(REPO)}, start_new_session=True,
        # A shell's background jobs ignore SIGINT (a suite run with &); a terminal's don't.
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    try:
        progress = ""
        if when == "the fork server starts":
            deadline = time.monotonic() + 60
            while (not _fork_server_of(process.pid) and process.poll() is None
                   and time.monotonic() < deadline):
                time.sleep(0.02)
        else:  # the first run is in: its worker waits while lander records it
            for progress in process.stderr:
                if " 1/3 runs" in progress:
                    break
        os.killpg(process.pid, signal.SIGINT)
        stdout, stderr = process.communicate(timeout=100)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    assert "Traceback" not in stderr, stderr
    assert process.returncode == 130, stderr
    lines = stderr.splitlines()
    assert lines[-1] == "lander campaign: interrupted"
    assert "finished run(s) kept in" in lines[-2] and "the same command flies the rest" in lines[-2]



def test_a_terminal_that_cannot_show_a_name_gets_escapes_not_a_crash(tmp_path, monkeypatch):
    path = tmp_path / "mission ü 火星.yaml"
    path.write_text(SCRIPTED.read_text())
    raw = io.BytesIO()
    monkeypatch.setattr(sys, "stdout", io.TextIOWrapper(raw, encoding="ascii"))
    assert main(["validate", str(path)]) == 0
    sys.stdout.flush()
    assert b"mission \\xfc \\u706b\\u661f.yaml" in raw.getvalue()


def test_a_mission_named_in_a_script_the_font_lacks_draws_without_warnings(tmp_path, capsys):
    path = tmp_path / "m.yaml"
    path.write_text(SCRIPTED.read_text().replace("name: demo", 'name: "火星 ✈"'))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["fly", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert [str(w.message) for w in caught if "Glyph" in str(w.message)] == []
    assert (tmp_path / "out" / "report.png").is_file()
