"""Shared test fixtures."""

from __future__ import annotations

import pytest
import torch

from pasta.plugins import get_plugins


@pytest.fixture(autouse=True)
def _one_torch_thread():
    """Tests run many small tensor ops; one thread avoids oversubscribing shared 2-core machines."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture
def fresh_plugins(monkeypatch):
    """Rescan entry points on demand; afterwards restore sys.path (fake distributions) and rescan."""
    yield lambda: get_plugins(refresh=True)
    monkeypatch.undo()
    get_plugins(refresh=True)
