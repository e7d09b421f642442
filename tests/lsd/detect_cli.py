"""Running ``lander detect`` in-process for the LiDAR file tests: only the detect command is
imported (the others' imports cost seconds), and its quiet form."""

from __future__ import annotations

import pytest

from autonomy import cli


@pytest.fixture(autouse=True)
def only_detect(monkeypatch):
    """Imported by a test module, every test of it runs with only ``detect`` registered."""
    monkeypatch.setattr(cli, "COMMAND_MODULES", ("autonomy.cli.detect",))


def lander(*argv) -> int:
    """``lander detect --quiet ARGV...``; its exit code."""
    return cli.main(["detect", "--quiet", *map(str, argv)])
