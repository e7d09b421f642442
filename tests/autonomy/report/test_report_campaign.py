"""campaign.html: outcomes per variant and every run linked to its own flight page."""

from __future__ import annotations

import re
from pathlib import Path

from autonomy.campaign import run_campaign
from autonomy.campaign.worker import error_record, fly_run
from autonomy.cli import main
from autonomy.cli.demo import mission_path
from autonomy.config import load_mission


class InProcess:
    """A campaign backend flying the runs here, one after the other (no worker start-up)."""

    workers = 1

    def run(self, tasks):
        for task in tasks:
            yield fly_run(task)


def test_campaign_page_links_each_run_to_its_flight_page(tmp_path, capsys, chromium):
    out = tmp_path / "campaign"
    run_campaign(load_mission(mission_path("demo.yaml")), runs=1, out_dir=out,
                 backend=InProcess(), vary=["landing.verification_altitude=2.5,4"], quiet=True,
                 name="demo")
    page = (out / "campaign.html").read_text(encoding="utf-8")
    links = re.findall(r'href="([^"]+)"', page)
    assert links == ["runs/v000-r00000/report.html", "runs/v001-r00000/report.html"]
    for link in links:
        run = out / Path(link).parent
        assert (run / "report.html").is_file() and (run / "summary.json").is_file()
        assert not (run / "report.png").exists()  # a campaign writes the page, not the png
    assert "verification_altitude=2.5" in page and "verification_altitude=4" in page
    assert re.findall(r"class=outcome[^>]*>([^<]+)</span>", page) == ["landed safe"] * 2

    report = chromium.inspect((out / "campaign.html").resolve().as_uri(), [
        ("eval", "document.querySelectorAll('a').length"),
        ("eval", "document.querySelector('img').naturalWidth"),
    ])
    assert report.exceptions == [] and report.console_errors == []
    assert [u for u in report.requests if not u.startswith(("file:", "data:"))] == []
    assert report.results[0] == 2 and report.results[1] > 100  # the plot is inline

    assert main(["replay", str(out), "--print"]) == 0
    assert capsys.readouterr().out.strip() == str(out / "campaign.html")


def test_campaign_without_pages_gives_its_runs_no_folder(tmp_path):
    seen = []

    class Recording(InProcess):
        def run(self, tasks):
            seen.extend(t.out_dir for t in tasks)
            return (error_record(t, "not flown here") for t in tasks)

    mission = load_mission(mission_path("demo.yaml"))
    run_campaign(mission, runs=2, out_dir=tmp_path / "a", backend=Recording(), quiet=True,
                 pages=False)
    assert seen == [None, None]
