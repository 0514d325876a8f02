"""What pasta reads when it lists plugins: the plate tool and the press skill.

Registration is metadata only: this module imports neither torch nor taichi; the skill class is named by a
``"module:Class"`` string that pasta imports when it builds the skill.
"""

from __future__ import annotations

from dataclasses import dataclass

from pasta.core import SkillSpec, ToolSpec
from pasta.core.tool import ActionChannel, Box
from pasta.plugins import hookimpl

#: plate half extents (x, y: thickness, z), metres: wide enough for the flattest piece the skill makes, and 6 cm
#: (4 grid cells) thick: dough pressed hard flows through a plate one grid cell thick
PLATE_HALF = (0.075, 0.03, 0.075)
#: the plate's bottom stops 2 cm above the floor (y = 0.02 at the default grid). A kinematic tool driven into the
#: floor leaves the dough nowhere to go but through it: without the stop, trajectory optimisation found that
#: driving the plate to the floor, with the dough passing through it, matched its targets best
PLATE_LOWEST_BOTTOM = 0.04

PLATE = ToolSpec(
    "plate",
    description="a flat horizontal plate that moves up and down",
    primitives=(Box(half=PLATE_HALF),),
    action=(ActionChannel("y", 0.005),),  # 5 mm per env step at action 1
    park=(0.5, 0.6, 0.85),
    min_height=PLATE_LOWEST_BOTTOM + PLATE_HALF[1],
    friction=0.5,
    color="tab:purple",
)

SPEC = SkillSpec("press", n_in=1, n_out=1, tool="plate", description="flatten a piece with the plate")


@dataclass
class PressConfig:
    """Settings of the press skill.

    Attributes:
        max_steps: env-step limit of one execution (the learned policy stops earlier by itself).
        flatten_min, flatten_max: a demonstration's target keeps this fraction of the piece's height
            (its footprint grows so that the volume stays the same).
        clearance: gap between the plate's bottom and the piece's top at the approach (metres).
    """

    max_steps: int = 30
    flatten_min: float = 0.3
    flatten_max: float = 0.42
    clearance: float = 0.004


@hookimpl
def pasta_register_tools(register):
    register(spec=PLATE)


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_press.skill:PressSkill", config=PressConfig)
