"""Every registered plugin runs the conformance checker: a new plugin is tested with no new test code."""

import pytest

from pasta.plugins import get_plugins
from pasta.testing import check_planner, check_skill, configured, small_budget

PLUGINS = get_plugins()


@pytest.mark.parametrize("name", PLUGINS.skills.names())
def test_registered_skill_conforms(name):
    check_skill(PLUGINS.skills.create(name))


@pytest.mark.parametrize("name", PLUGINS.planners.names())
def test_registered_planner_conforms(name):
    check_planner(configured(PLUGINS.planners, name, small_budget(PLUGINS.planners, name)), name=name)
