"""What a plugin author tests a plugin with: contract suites, conformance checkers and an analytic problem.

Everything is imported from here (the underscored modules are private)::

    from pasta.testing import PlannerContract, SkillContract, TaskContract

    class TestPinch(SkillContract):           # pytest collects the inherited tests
        skill_name = "pinch"

- Contract suites (pytest classes; set the class attributes): :class:`SkillContract` (``skill_name``),
  :class:`PlannerContract` (``planner_name``, ``planner_overrides``), :class:`TaskContract` (``task_name``,
  ``task_overrides``, ``seed``).
- Conformance checkers, each raising :class:`PluginConformanceError` that names the first broken rule:
  :func:`check_skill`, :func:`check_encoder`, :func:`check_plan`, :func:`check_planner`, :func:`check_task`;
  :func:`configured` builds a registered component with config overrides, :func:`small_budget` the search
  budget (:data:`SMALL_BUDGET`) a conformance run needs.
- The analytic problem with a known optimum, for planners without trained networks:
  :func:`analytic_problem` (latents ``(K, 5)``), its skills ``split``/``move``/``flatten``
  (:func:`analytic_skills`, optimum :data:`OPTIMAL_SKELETON`), :class:`AnalyticEncoder`,
  :class:`AnalyticCost`, the brute-force :class:`ReferencePlanner`, and :class:`AnalyticPlugin`, an
  in-process plugin registering all of them (``pasta.plugins.discover(extra={"analytic": AnalyticPlugin()})``).

This module sits above the machinery it checks (planning, the simulator, demonstration scenes) and beside
the plugin packages; ``pasta.plugins`` itself holds only the hook specifications and the registry.
"""

from pasta.testing._analytic import (
    OPTIMAL_SKELETON,
    AnalyticCost,
    AnalyticEncoder,
    AnalyticPlugin,
    FlattenSkill,
    MoveSkill,
    ReferencePlanner,
    ReferencePlannerConfig,
    SplitSkill,
    analytic_problem,
    analytic_skills,
)
from pasta.testing._checks import (
    SMALL_BUDGET,
    PluginConformanceError,
    check_encoder,
    check_plan,
    check_planner,
    check_skill,
    check_task,
    configured,
    small_budget,
)
from pasta.testing._contracts import PlannerContract, SkillContract, TaskContract

__all__ = [
    "OPTIMAL_SKELETON",
    "SMALL_BUDGET",
    "AnalyticCost",
    "AnalyticEncoder",
    "AnalyticPlugin",
    "FlattenSkill",
    "MoveSkill",
    "PlannerContract",
    "PluginConformanceError",
    "ReferencePlanner",
    "ReferencePlannerConfig",
    "SkillContract",
    "SplitSkill",
    "TaskContract",
    "analytic_problem",
    "analytic_skills",
    "check_encoder",
    "check_plan",
    "check_planner",
    "check_skill",
    "check_task",
    "configured",
    "small_budget",
]
