"""Registers the 'receding_horizon' planner. Imports only its config, so listing plugins stays cheap."""

from pasta.plugins import hookimpl
from pasta_planner_receding_horizon.config import RecedingHorizonConfig


@hookimpl
def pasta_register_planners(register):
    register(name="receding_horizon", factory="pasta_planner_receding_horizon.planner:RecedingHorizonPlanner", config=RecedingHorizonConfig, summary="optimise a window of steps, commit the first, slide (long tasks)")
