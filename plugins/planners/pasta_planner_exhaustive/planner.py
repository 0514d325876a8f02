"""The 'exhaustive' planner."""

from __future__ import annotations

from pasta.core import MissingComponentError, Plan, Planner, PlanningProblem


class ExhaustivePlanner(Planner):
    """every skill sequence with the right cardinality, random attention, Adam on sub-goal latents (PASTA)."""

    name = "exhaustive"

    def plan(self, problem: PlanningProblem) -> Plan:
        raise MissingComponentError("planner 'exhaustive' is registered but its search is not implemented yet (planners issue)")
