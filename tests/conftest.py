"""Shared test fixtures."""

from __future__ import annotations

import pytest

from pasta.plugins import get_plugins


@pytest.fixture
def fresh_plugins(monkeypatch):
    """Rescan entry points on demand; afterwards restore sys.path (fake distributions) and rescan."""
    yield lambda: get_plugins(refresh=True)
    monkeypatch.undo()
    get_plugins(refresh=True)
