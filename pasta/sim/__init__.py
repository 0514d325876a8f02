"""pasta.sim: a Taichi MLS-MPM dough simulator with rigid tools (knife, pusher, roller).

Importing this package does not start Taichi; constructing a ``Simulator`` does (once per process).
"""

from .config import RUNTIME_PARAMS, SimConfig
from .render import render_png
from .scene import FLOOR_Y, box_particles, crs_dough, sphere_particles
from .simulator import Observation, SimState, SimulationDiverged, Simulator
from .tools import PARK_POSES, TOOL_ACTION_DIMS, TOOL_ACTION_SCALES, TOOL_NAMES

__all__ = [
    "FLOOR_Y",
    "PARK_POSES",
    "RUNTIME_PARAMS",
    "TOOL_ACTION_DIMS",
    "TOOL_ACTION_SCALES",
    "TOOL_NAMES",
    "Observation",
    "SimConfig",
    "SimState",
    "SimulationDiverged",
    "Simulator",
    "box_particles",
    "crs_dough",
    "render_png",
    "sphere_particles",
]
