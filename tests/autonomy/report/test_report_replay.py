"""`lander replay OUT_DIR`: the page's path (or a browser), and one clear line on bad input."""

from __future__ import annotations

import json
import re
import shutil

from autonomy.cli import main


def test_replay_prints_the_flight_page(demo_flight, capsys):
    assert main(["replay", str(demo_flight.out_dir), "--print"]) == 0
    assert capsys.readouterr().out.strip() == str(demo_flight.out_dir / "report.html")


def test_replay_opens_the_page_in_a_browser_where_there_is_a_display(demo_flight, capsys,
                                                                     monkeypatch):
    opened = []
    monkeypatch.setattr("webbrowser.open", lambda url: opened.append(url) or True)
    monkeypatch.setenv("DISPLAY", ":0")
    assert main(["replay", str(demo_flight.out_dir)]) == 0
    assert opened == [(demo_flight.out_dir / "report.html").resolve().as_uri()]
    assert "opened" in capsys.readouterr().out
    # Over ssh (no display) it prints the path rather than start a text browser here.
    monkeypatch.delenv("DISPLAY")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["replay", str(demo_flight.out_dir)]) == 0
    assert capsys.readouterr().out.strip() == str(demo_flight.out_dir / "report.html")
    assert len(opened) == 1


def test_replay_of_a_folder_without_a_report_is_one_line_exit_2(tmp_path, capsys):
    cases = [tmp_path / "missing", tmp_path / "empty", tmp_path / "no-events",
             tmp_path / "file.txt", tmp_path / "summary-only"]
    cases[1].mkdir()
    cases[2].mkdir()
    (cases[2] / "events.jsonl").write_text("{}\n{not json\n")
    cases[3].write_text("x")
    cases[4].mkdir()
    (cases[4] / "summary.json").write_text("{}")
    for folder in cases:
        assert main(["replay", str(folder), "--print"]) == 2
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"lander replay: error: {folder}")
        assert captured.out == "" and "Traceback" not in captured.err


def test_a_killed_flight_replays_from_its_logs_to_their_last_record(demo_flight, tmp_path,
                                                                      capsys, chromium):
    """A flight killed mid-way leaves its logs cut short and no report: the page is rebuilt
    from them (track from flight.tlog, tree to the last whole transition of tree.btlog)."""
    out = tmp_path / "killed"
    shutil.copytree(demo_flight.out_dir, out)
    for name in ("report.html", "report.png", "summary.json"):
        (out / name).unlink()
    for name in ("events.jsonl", "flight.tlog", "tree.btlog"):
        data = (out / name).read_bytes()
        head = data.index(b"</root>") + len(b"</root>") + 8 if name == "tree.btlog" else 0
        cut = head + int((len(data) - head) * 0.6) + 3  # inside a record
        (out / name).write_bytes(data[:cut])
    assert main(["replay", str(out), "--print"]) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() == str(out / "report.html")
    assert "rebuilt from its logs" in captured.err and len(captured.err.splitlines()) == 1
    text = (out / "report.html").read_text(encoding="utf-8")
    page = json.loads(re.search(r'<script id="flight-data" type="application/json">(.*?)'
                                r"</script>", text, re.S).group(1))
    assert page["summary"]["outcome"] == "unfinished"
    assert page["tree"]["source"] == "tree.btlog" and page["tree"]["truncated"]
    full = demo_flight.data.trace
    cut_at = page["trace"]["t"][-1]
    assert 0.3 * full.t[-1] < cut_at < 0.9 * full.t[-1]  # the track, to where the log ends
    i = min(range(len(full.t)), key=lambda k: abs(full.t[k] - cut_at))
    assert abs(page["trace"]["x"][-1] - full.xyz[i][0]) < 1.0
    assert abs(page["trace"]["z"][-1] - full.xyz[i][2]) < 1.0
    assert [p for _, p in page["phases"]] == [
        p for t, p in full.phases if t <= page["end"]]
    report = chromium.inspect((out / "report.html").resolve().as_uri(),
                                  [("eval", "document.body.getAttribute('data-ready')")])
    assert report.exceptions == [] and report.console_errors == [] and report.results == ["1"]
    # Once rebuilt, the page is there: replay opens it as any other.
    assert main(["replay", str(out), "--print"]) == 0
    assert capsys.readouterr().err == ""
