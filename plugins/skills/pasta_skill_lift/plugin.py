"""Registers the 'lift' skill, its spatula and the raised cutting board (metadata only: no torch, no taichi).

The board is registered here, not by a task: it is the surface the lift skill's expert and heuristic set
dough down on (:data:`pasta_skill_lift.tool.BOARD_TOP` is the expert's default surface height), so a task
or a demonstration that uses ``lift`` gets the board from the same package.
"""

from dataclasses import dataclass

from pasta.core import SceneNeeds, SkillSpec
from pasta.plugins import hookimpl
from pasta_skill_lift.tool import BOARD, BOARD_TOP, SPATULA

#: the lift sets dough down on a raised surface (the board's top is 7 cm; the floor, 2 cm, is what push is for):
#: any standing static tool whose top lies 4-25 cm high will do, so a user's own shelf or stand qualifies too
SPEC = SkillSpec(name="lift", n_in=1, n_out=1, tool="spatula",
                 description="lift one dough piece with the spatula and set it down on the raised board",
                 needs=SceneNeeds(surface=(0.04, 0.25), why="a raised surface to set the dough down on"))


@dataclass
class LiftConfig:
    """Settings of the lift skill (distances in metres of the unit-cube workspace).

    Attributes:
        max_steps: env-step limit of one execution.
        scoop_depth: at the approach pose the plate's top is this far above the piece's bottom (1st
            percentile of y): the plate is slid under the piece's bottom layer. With the top level with
            the bottom (0) the rising plate left most of the dough behind (measured: a 6.5 cm cube rose
            1 cm and stayed put when the plate moved on); 1 cm carried it.
        clearance: the piece's bottom is carried this far above the destination surface.
        sink: the plate's top goes this far below the destination surface to set the dough down (the
            board holds the dough while the plate passes below its top: tools do not collide).
        speed: top plate speed, as a fraction of the full 0.01 per env step (faster lifts let the plate
            pass through a thin bottom layer of dough).
        slow_distance: the plate slows down linearly over this last distance of each move.
        tolerance: done with a move when within this of its target.
        surface_y: expert: height of the surface the dough is set on (default: the board's top);
            heuristic: the lowest surface it sets down on (a decoded goal's bottom may lie lower).
        target_x_min, target_x_max, target_z_min, target_z_max: expert sampling box of the piece's
            target centroid (default: on the board, away from its edges).
    """

    max_steps: int = 160
    scoop_depth: float = 0.012
    clearance: float = 0.02
    sink: float = 0.03
    speed: float = 0.5
    slow_distance: float = 0.03
    tolerance: float = 0.0015
    surface_y: float = BOARD_TOP
    target_x_min: float = 0.24
    target_x_max: float = 0.36
    target_z_min: float = 0.42
    target_z_max: float = 0.58


@hookimpl
def pasta_register_skills(register):
    register(spec=SPEC, factory="pasta_skill_lift.skill:LiftSkill", config=LiftConfig)


@hookimpl
def pasta_register_tools(register):
    register(spec=SPATULA)
    register(spec=BOARD)
