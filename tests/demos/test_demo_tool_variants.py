"""Skill.demo_tools takes the demo variant: the roll's `board` variant stands up the lift package's board."""

import numpy as np

from pasta.core import ToolPose
from pasta.demos.generate import demo_tools
from pasta.demos.scene import scene_boxes
from pasta.plugins import get_plugins


def test_roll_board_variant_puts_a_cube_on_the_board():
    from pasta_skill_lift.tool import BOARD_HALF, BOARD_POSE, BOARD_TOP

    roll = get_plugins().skills.create("roll")
    [(centre, size)] = scene_boxes(roll, np.random.default_rng(0), 0.02, "board")
    assert abs(centre[1] - size[1] / 2 - BOARD_TOP) < 1e-9  # resting on the board's top, not the floor
    assert abs(centre[0] - BOARD_POSE[0]) + size[0] / 2 < BOARD_HALF[0]  # over the board
    assert demo_tools(roll, "board") == {"board": ToolPose(BOARD_POSE, 0.0)}
    assert demo_tools(roll, "default") == {}
    [(floor_centre, floor_size)] = scene_boxes(roll, np.random.default_rng(0), 0.02, "default")
    assert abs(floor_centre[1] - floor_size[1] / 2 - 0.02) < 1e-9


def test_an_override_without_the_variant_argument_still_works():
    class OldStyle:
        def demo_tools(self):
            return {"board": ToolPose((0.3, 0.045, 0.5), 0.0)}

    assert demo_tools(OldStyle(), "anything") == {"board": ToolPose((0.3, 0.045, 0.5), 0.0)}
