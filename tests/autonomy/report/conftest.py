"""Fixtures of the report tests: one demo flight with its report folder, headless Chromium."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

HERE = str(Path(__file__).parent)
if HERE not in sys.path:  # the `browser` helper module beside this file
    sys.path.insert(0, HERE)


@pytest.fixture(scope="session")
def demo_flight(tmp_path_factory):
    """missions/demo.yaml (scripted sites over flat ground: quick) flown once in lockstep
    into a report folder: the FlightResult."""
    from autonomy.cli.demo import mission_path
    from autonomy.config import load_mission
    from autonomy.runner import fly

    out = tmp_path_factory.mktemp("demo-report")
    return fly(load_mission(mission_path("demo.yaml")), out_dir=out)


@pytest.fixture(scope="session")
def chromium():
    """A headless Chromium (:class:`browser.Chromium`, one for the session): Debian's
    package, installed with apt-get when missing; the test is skipped only when it cannot be
    installed here."""
    import browser

    path = browser.install_chromium()
    if path is None:
        pytest.skip("chromium is not installed and apt-get could not install it (needs root "
                    "and the Debian archive); install Debian's 'chromium' package")
    running = browser.Chromium(path)
    yield running
    running.close()
