"""The 'sampling' planner."""

from __future__ import annotations

from pasta.core import MissingComponentError, Plan, Planner, PlanningProblem


class SamplingPlanner(Planner):
    """the same search without gradients: cross-entropy method over sub-goal latents."""

    name = "sampling"

    def plan(self, problem: PlanningProblem) -> Plan:
        raise MissingComponentError("planner 'sampling' is registered but its search is not implemented yet (planners issue)")
