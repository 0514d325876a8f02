import pytest

from pasta.core import Planner, PluginNotFoundError, PluginValidationError, SkillSpec
from pasta.plugins import PluginInfo, get_plugins
from pasta.plugins.registry import discover
from pasta.testing import AnalyticPlugin, MoveSkill

BUILTIN_SKILLS = {"cut": (1, 2, "knife"), "push": (1, 1, "pusher"), "roll": (1, 1, "roller")}
BUILTIN_PLANNERS = {"exhaustive", "prefix_beam", "receding_horizon", "sampling"}


def test_builtins_are_registered_through_entry_points():
    plugins = get_plugins()
    for name, (n_in, n_out, tool) in BUILTIN_SKILLS.items():
        info = plugins.skills.info(name)
        assert (info.spec.n_in, info.spec.n_out, info.spec.tool) == (n_in, n_out, tool)
        assert info.distribution == "pasta-dough" and info.plugin == name
    assert BUILTIN_PLANNERS <= set(plugins.planners.names())
    assert not plugins.failures


def test_unknown_planner_lists_known_planners():
    with pytest.raises(PluginNotFoundError) as err:
        get_plugins().planners.info("exhaustiv")
    message = str(err.value)
    assert "unknown planner 'exhaustiv'; did you mean 'exhaustive'?" in message
    assert all(name in message for name in BUILTIN_PLANNERS)


def test_create_builds_skill_and_planner_with_default_config():
    plugins = get_plugins()
    cut = plugins.skills.create("cut")
    assert cut.name == "cut" and cut.n_out == 2
    planner = plugins.planners.create("sampling")
    assert isinstance(planner, Planner) and planner.config.name == "sampling"


def test_in_process_plugins_register_every_kind():
    plugins = discover(extra={"analytic": AnalyticPlugin()})
    assert {"split", "move", "flatten"} <= set(plugins.skills.names())
    assert "reference" in plugins.planners
    assert "analytic" in plugins.encoders and "analytic" in plugins.cost_models
    assert plugins.skills.info("move").distribution == "(in-process)"


def test_load_rejects_factory_not_honouring_contract():
    bad_spec = PluginInfo("skill", "move", "pasta.testing._analytic:MoveSkill", spec=SkillSpec("move", 2, 1, "hand"))
    with pytest.raises(PluginValidationError, match="differs from the registered"):
        bad_spec.load()
    wrong_base = PluginInfo("planner", "x", "pasta.testing._analytic:MoveSkill")
    with pytest.raises(PluginValidationError, match="not a pasta.core.Planner subclass"):
        wrong_base.load()
    missing = PluginInfo("skill", "move", "pasta.plugins.nowhere:Nothing", spec=MoveSkill.spec, plugin="p", distribution="d")
    with pytest.raises(PluginValidationError, match="cannot import factory 'pasta.plugins.nowhere:Nothing'"):
        missing.load()
