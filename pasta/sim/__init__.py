"""pasta.sim: a Taichi MLS-MPM dough simulator with rigid tools that plugins register (``ToolSpec``).

Importing this package does not start Taichi; constructing a ``Simulator`` does (once per process).
"""

from .config import RUNTIME_PARAMS, SimConfig
from .render import render_png
from .scene import FLOOR_Y, box_particles, crs_dough, sphere_particles
from .simulator import Observation, SimState, SimulationDiverged, Simulator
from .tools import MAX_TOOLS, ToolTable

__all__ = [
    "FLOOR_Y",
    "MAX_TOOLS",
    "RUNTIME_PARAMS",
    "Observation",
    "SimConfig",
    "SimState",
    "SimulationDiverged",
    "Simulator",
    "ToolTable",
    "box_particles",
    "crs_dough",
    "render_png",
    "sphere_particles",
]
