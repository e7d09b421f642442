"""The README is the front door: every page it links to exists, and each task a new user
comes for is reachable from it (the docs site's own links are checked by `mkdocs build
--strict` in `make test`)."""

from __future__ import annotations

import re
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[2]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


def readme_links() -> list[str]:
    return [t for t in LINK.findall((REPO / "README.md").read_text()) if "://" not in t]


def test_every_relative_link_of_the_readme_exists():
    links = readme_links()
    assert links
    missing = [t for t in links if not (REPO / t).exists()]
    assert not missing, f"README links to missing files: {missing}"


def test_every_page_the_readme_links_is_in_the_site_nav():
    nav = yaml.safe_load((REPO / "mkdocs.yml").read_text())["nav"]

    def pages(node) -> list[str]:
        if isinstance(node, str):
            return [node]
        if isinstance(node, list):
            return [p for item in node for p in pages(item)]
        return [p for value in node.values() for p in pages(value)]

    in_nav = set(pages(nav))
    docs = [t.removeprefix("docs/") for t in readme_links()
            if t.startswith("docs/") and t.endswith(".md")]
    assert docs and not set(docs) - in_nav


def test_the_user_tasks_are_one_click_from_the_readme():
    links = set(readme_links())
    for page in ("docs/tutorials/first-flight.md", "docs/tutorials/your-terrain.md",
                 "docs/tutorials/ground-stations.md", "docs/tutorials/autopilot-sitl.md",
                 "docs/tutorials/campaigns.md", "docs/tutorials/mission-tree.md",
                 "docs/design/index.md", "docs/benchmarks.md", "docs/reference/python-api.md"):
        assert page in links, page
