"""Registers the 'sampling' planner. Imports only its config, so listing plugins stays cheap."""

from pasta.plugins import hookimpl
from pasta_planner_sampling.config import SamplingConfig


@hookimpl
def pasta_register_planners(register):
    register(name="sampling", factory="pasta_planner_sampling.planner:SamplingPlanner", config=SamplingConfig, summary="the same search without gradients: cross-entropy method over sub-goal latents")
