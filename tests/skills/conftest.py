"""Fixtures of the skill tests."""

import pytest


@pytest.fixture
def skills():
    from pasta.plugins import get_plugins

    p = get_plugins()
    return {name: p.skills.create(name) for name in ("cut", "push", "roll")}
