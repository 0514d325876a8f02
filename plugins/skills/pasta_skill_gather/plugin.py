"""Registers the 'gather' skill and the gripper (metadata only: no torch, no taichi).

Cardinality 3 -> 1: the scattered dough is three lumps, each its own entity under the default scene
decomposition (DBSCAN eps 0.03; the lumps lie 3.5-5 cm apart), and gathering presses them into one
piece. Keeping the lumps as entities, rather than one scene entity with a larger DBSCAN radius as the
paper does, lets the planner, the executor, the training data and the demonstrations (one box per
consumed piece) use the set representation unchanged; the price is a fixed number of lumps.
"""

from dataclasses import dataclass

from pasta.core import SkillSpec
from pasta.plugins import hookimpl
from pasta_skill_gather.tool import GRIPPER

SPEC = SkillSpec(name="gather", n_in=3, n_out=1, tool="gripper",
                 description="squeeze three dough lumps into one compact piece with the gripper")


@dataclass
class GatherConfig:
    """Settings of the gather skill (distances in metres of the unit-cube workspace).

    Attributes:
        max_steps: env-step limit of one execution.
        lift: height of the finger bottoms above the lumps' bottom at the approach pose; negative: the
            fingers reach into the floor band below the dough (dough squeezed under fingers that stand
            on its bottom layer escapes outwards: 8.6 cm instead of 7.6 cm long at a 6.5 cm gap).
        speed: closing speed, a fraction of the full 0.01 aperture change per env step.
        width_min, width_max: expert sampling: the final gap between the fingers (never wider than
            ``max_fraction`` of the lumps' current extent along the closing axis).
        max_fraction: see ``width_min``.
        width_offset: heuristic: it closes to the goal's extent along the closing axis (1st-99th
            percentile) plus this. The gathered piece ends wider than the gap the fingers closed to (the
            dough springs back and bulges past the fingers' ends): by 1.5 cm at a 6 cm gap, 0.6 cm at 8 cm,
            1.1 cm on average (4 demo scenes).
        tolerance: done when the gap is within this of its target.
    """

    max_steps: int = 80
    lift: float = -0.015
    speed: float = 0.5
    width_min: float = 0.06
    width_max: float = 0.08
    max_fraction: float = 0.6
    width_offset: float = -0.011
    tolerance: float = 0.0005


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_gather.skill:GatherSkill", config=GatherConfig)


@hookimpl
def pasta_register_tools(register):
    register(spec=GRIPPER)
