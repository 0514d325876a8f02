"""The contract suites exercised with the analytic test plugins and the reference planner."""

import dataclasses

import pytest

from pasta.plugins.registry import discover
from pasta.testing import (
    AnalyticPlugin,
    PlannerContract,
    PluginConformanceError,
    ReferencePlanner,
    ReferencePlannerConfig,
    SkillContract,
    check_planner,
)

ANALYTIC = discover(extra={"analytic": AnalyticPlugin()})


class AnalyticPlugins:
    # the analytic skills' tools are names only (no geometry): there is nothing to simulate, so the
    # simulator part of the skill contract is not collected for them (the built-in skills run it)
    test_actions_fit_tool_layout = None

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
    from pasta.testing import check_encoder

    check_encoder(ANALYTIC.encoders.create("analytic"))


class _Distorted(ReferencePlanner):
    """The reference planner with one contract broken (``flaw``), to show the checker catches it."""

    flaw = ""

    def plan(self, problem):
        if self.flaw == "skeleton" and problem.skeleton is not None:
            problem = dataclasses.replace(problem, skeleton=None)
        plan = super().plan(problem)
        if self.flaw == "seed":
            plan = dataclasses.replace(plan, seed=problem.seed + 1)
        if self.flaw == "name":
            plan = dataclasses.replace(plan, planner="someone_else")
        if self.flaw == "goal":
            plan = dataclasses.replace(plan, goal=plan.initial)
        return plan


@pytest.mark.parametrize("flaw, message", [
    ("skeleton", r"ignores the given problem.skeleton \['move', 'split', 'flatten'\]"),
    ("seed", r"plan.seed is 1, the problem's seed is 0"),
    ("name", r"plan.planner is 'someone_else', the planner is registered as 'reference'"),
    ("goal", r"plan.goal \(\(1.0, 0.0, 0.69.*differs from the problem's goal latents \(\(0.6"),
])
def test_check_planner_catches_a_broken_planner(flaw, message):
    planner = _Distorted(ReferencePlannerConfig(num_samples=32, iterations=5))
    planner.flaw = flaw
    with pytest.raises(PluginConformanceError, match=message):
        check_planner(planner, name="reference")
