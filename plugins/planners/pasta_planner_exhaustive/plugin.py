"""Registers the 'exhaustive' planner. Imports only its config, so listing plugins stays cheap."""

from pasta.plugins import hookimpl
from pasta_planner_exhaustive.config import ExhaustiveConfig


@hookimpl
def pasta_register_planners(register):
    register(name="exhaustive", factory="pasta_planner_exhaustive.planner:ExhaustivePlanner", config=ExhaustiveConfig, summary="every skill sequence with the right cardinality, random attention, Adam on sub-goal latents (PASTA)")
