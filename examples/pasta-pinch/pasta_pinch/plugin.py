"""What pasta reads when it lists plugins: the pincer tool, the pinch skill and the beam planner.

Registration is metadata only: this module imports neither torch nor taichi, and the skill and planner
classes are named by ``"module:Class"`` strings that pasta imports when they are built.
"""

from __future__ import annotations

from dataclasses import dataclass

from pasta.core import SkillSpec, ToolSpec
from pasta.core.tool import ActionChannel, FingerPair
from pasta.plugins import hookimpl
from pasta.planning import LatentPlannerConfig

#: finger half extents (x: thickness, y: height, z: width) and the gap the fingers start with (metres)
FINGER_HALF = (0.01, 0.04, 0.05)
OPEN_APERTURE = 0.3

PINCER = ToolSpec(
    "pincer",
    description="a parallel gripper: two fingers whose gap is an action component",
    primitives=(FingerPair(half=FINGER_HALF, aperture=OPEN_APERTURE, min_aperture=0.0, max_aperture=0.34),),
    # (dx, dy, dz) 1 cm, yaw 0.025 rad and the aperture 1 cm per env step at action 1
    action=(ActionChannel("x", 0.01), ActionChannel("y", 0.01), ActionChannel("z", 0.01),
            ActionChannel("yaw", 0.025), ActionChannel("open", 0.01)),
    park=(0.5, 0.8, 0.85),
    friction=1.0,
    color="tab:orange",
)

SPEC = SkillSpec("pinch", n_in=2, n_out=1, tool="pincer", description="squeeze two pieces into one with the pincer")


@dataclass
class PinchConfig:
    """Settings of the pinch skill (metres).

    Attributes:
        max_steps: env-step limit of one execution.
        squeeze_min, squeeze_max: the expert closes the gap to this fraction of the two pieces' summed
            widths along the line between them (below 1: they are pressed into one piece).
        lift: height of the finger bottoms above the floor at the approach.
        tolerance: the heuristic controller stops this close to the goal piece's width.
    """

    max_steps: int = 40
    squeeze_min: float = 0.75
    squeeze_max: float = 0.9
    lift: float = 0.003
    tolerance: float = 0.005


@dataclass
class BeamConfig(LatentPlannerConfig):
    """The beam planner: every skill sequence is probed with a small search, the best ``width`` get the
    full search (``num_samples`` samples, ``iterations`` Adam steps) of the shared latent optimiser."""

    width: int = 2
    probe_samples: int = 64
    probe_iterations: int = 20


@hookimpl
def pasta_register_tools(register):
    register(spec=PINCER)


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_pinch.skill:PinchSkill", config=PinchConfig)


@hookimpl
def pasta_register_planners(register):
    register(name="beam", factory="pasta_pinch.beam:BeamPlanner", config=BeamConfig,
             summary="probe every skill sequence cheaply, search the best few fully")
