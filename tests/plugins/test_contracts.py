"""The contract suites exercised with the analytic test plugins and the reference planner."""

from pasta.plugins.analytic import AnalyticPlugin
from pasta.plugins.registry import discover
from pasta.plugins.testing import PlannerContract, SkillContract

ANALYTIC = discover(extra={"analytic": AnalyticPlugin()})


class AnalyticPlugins:
    def plugins(self):
        return ANALYTIC


class TestReferencePlanner(AnalyticPlugins, PlannerContract):
    planner_name = "reference"


class TestSplit(AnalyticPlugins, SkillContract):
    skill_name = "split"


class TestMove(AnalyticPlugins, SkillContract):
    skill_name = "move"


class TestFlatten(AnalyticPlugins, SkillContract):
    skill_name = "flatten"


def test_analytic_encoder_conforms():
    from pasta.plugins.checks import check_encoder

    check_encoder(ANALYTIC.encoders.create("analytic"))
