from pathlib import Path

import pytest

HERE = str(Path(__file__).parent)


@pytest.fixture
def fakes(monkeypatch):
    """The ``fake_flights`` module, importable by name in spawned worker processes too."""
    monkeypatch.syspath_prepend(HERE)
    import fake_flights

    return fake_flights
