"""`lander replay OUT_DIR`: the page's path (or a browser), and one clear line on bad input."""

from __future__ import annotations

from autonomy.cli import main


def test_replay_prints_the_flight_page(demo_flight, capsys):
    assert main(["replay", str(demo_flight.out_dir), "--print"]) == 0
    assert capsys.readouterr().out.strip() == str(demo_flight.out_dir / "report.html")


def test_replay_opens_the_page_in_a_browser(demo_flight, capsys, monkeypatch):
    opened = []
    monkeypatch.setattr("webbrowser.open", lambda url: opened.append(url) or True)
    assert main(["replay", str(demo_flight.out_dir)]) == 0
    assert opened == [(demo_flight.out_dir / "report.html").resolve().as_uri()]
    assert "opened" in capsys.readouterr().out


def test_replay_of_a_folder_without_a_report_is_one_line_exit_2(tmp_path, capsys):
    cases = [tmp_path / "missing", tmp_path / "empty", tmp_path / "logs-only",
             tmp_path / "file.txt"]
    cases[1].mkdir()
    cases[2].mkdir()
    (cases[2] / "events.jsonl").write_text("{}\n")
    cases[3].write_text("x")
    for folder in cases:
        assert main(["replay", str(folder), "--print"]) == 2
        captured = capsys.readouterr()
        lines = captured.err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith(f"lander replay: error: {folder}: ")
        assert captured.out == "" and "Traceback" not in captured.err
