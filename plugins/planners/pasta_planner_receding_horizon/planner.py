"""The 'receding_horizon' planner."""

from __future__ import annotations

from pasta.core import MissingComponentError, Plan, Planner, PlanningProblem


class RecedingHorizonPlanner(Planner):
    """optimise a window of steps, commit the first, slide (long tasks)."""

    name = "receding_horizon"

    def plan(self, problem: PlanningProblem) -> Plan:
        raise MissingComponentError("planner 'receding_horizon' is registered but its search is not implemented yet (planners issue)")
