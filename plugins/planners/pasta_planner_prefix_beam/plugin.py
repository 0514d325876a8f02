"""Registers the 'prefix_beam' planner. Imports only its config, so listing plugins stays cheap."""

from pasta.plugins import hookimpl
from pasta_planner_prefix_beam.config import PrefixBeamConfig


@hookimpl
def pasta_register_planners(register):
    register(name="prefix_beam", factory="pasta_planner_prefix_beam.planner:PrefixBeamPlanner", config=PrefixBeamConfig, summary="beam search over skill prefixes, then the shared optimiser on the best full sequences (long horizons)")
