"""The fuzz harness (harness.py, beside this file) as fixtures: one forked worker and one set
of input files for the whole module."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

import harness  # noqa: E402


@pytest.fixture(scope="session")
def fuzz(tmp_path_factory):
    """(runner, files, closed_port): a forked `lander` worker working in a scratch dir."""
    workdir = tmp_path_factory.mktemp("fuzz")
    files = harness.Files(workdir)
    runner = harness.Runner(workdir, deadline=120.0)
    yield runner, files, harness.closed_port()
    runner.close()
