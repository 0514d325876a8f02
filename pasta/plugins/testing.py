"""Reusable pytest contract suites for plugin authors (hydra's ``LauncherTestSuite`` pattern).

A plugin package tests itself with a few lines::

    from pasta.plugins.testing import SkillContract

    class TestPinch(SkillContract):
        skill_name = "pinch"

    class TestMyPlanner(PlannerContract):
        planner_name = "beam"
        planner_overrides = {"num_samples": 512}   # keep the test fast

``PlannerContract`` runs the planner on the analytic problem of :mod:`pasta.plugins.analytic`, whose
optimal skill sequence and attention are known.
"""

from __future__ import annotations

from typing import Any, ClassVar

from pasta.core import Planner, Skill
from pasta.plugins.analytic import OPTIMAL_SKELETON, analytic_problem
from pasta.plugins.checks import check_plan, check_planner, check_skill, configured
from pasta.plugins.registry import Plugins, get_plugins


class SkillContract:
    """Contract tests for a registered skill."""

    skill_name: ClassVar[str]

    def plugins(self) -> Plugins:
        return get_plugins()

    def make_skill(self) -> Skill:
        return self.plugins().skills.create(self.skill_name)

    def test_registered_spec_matches_class(self) -> None:
        info = self.plugins().skills.info(self.skill_name)
        assert info.spec == info.load().spec

    def test_conforms(self) -> None:
        check_skill(self.make_skill())


class PlannerContract:
    """Contract tests for a registered planner, on the analytic problem with a known optimum."""

    planner_name: ClassVar[str]
    planner_overrides: ClassVar[dict[str, Any]] = {}

    def plugins(self) -> Plugins:
        return get_plugins()

    def make_planner(self) -> Planner:
        return configured(self.plugins().planners, self.planner_name, self.planner_overrides)

    def test_conforms(self) -> None:
        check_planner(self.make_planner())

    def test_finds_optimal_skeleton_and_attention(self) -> None:
        problem = analytic_problem()
        plan = self.make_planner().plan(problem)
        check_plan(plan, problem)
        assert plan.skills == OPTIMAL_SKELETON
        split, move, flatten = plan.steps
        moved = split.state[move.inputs[0]]
        assert abs(moved[0] - 0.4) < 0.1, f"move must act on the size-0.4 piece, acted on {moved}"
        assert flatten.inputs[0] == 0, "flatten must act on the piece just moved (produced entities come first)"
        assert plan.final_cost < 0.01 and plan.score > 0.5
