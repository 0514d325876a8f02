"""The lift (spatula) and gather (gripper) skills: contract suites and their experts doing their job."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.decompose import decompose_labels
from pasta.core.errors import ConfigError
from pasta.plugins import get_plugins
from pasta.tasks.step import run_skill
from pasta.testing import SkillContract


class TestLift(SkillContract):
    skill_name = "lift"


class TestGather(SkillContract):
    skill_name = "gather"


def test_board_and_gripper_are_registered_tools():
    tools = get_plugins().tools
    assert tools.info("board").spec.is_static
    assert tools.info("spatula").spec.channels == ("x", "y", "z")
    assert tools.info("gripper").spec.finger_pair is not None


def test_other_plugins_find_the_board_through_the_registry():
    """The roll skill and the board tasks read where the board stands from its registered spec
    (ToolSpec.stand), not from the lift package: the same numbers, to the bit, as the lift package's own."""
    from pasta.core import ToolPose
    from pasta.demos.scene import standing_tool
    from pasta_skill_lift.tool import BOARD_POSE, BOARD_TOP

    board = standing_tool("board")
    assert board.stand == BOARD_POSE and board.stand_top == BOARD_TOP
    roll = get_plugins().skills.create("roll")
    assert roll.demo_tools("board") == {"board": ToolPose(BOARD_POSE, 0.0)} and roll.demo_tools() == {}
    (centre, size), = roll.demo_scene(np.random.default_rng(0), 0.02, "board")
    assert centre[1] - size[1] / 2 == pytest.approx(BOARD_TOP)  # the cube rests on the board's top
    with pytest.raises(ConfigError, match="tool 'bord' is not registered; did you mean 'board'"):
        standing_tool("bord")
    with pytest.raises(ConfigError, match="tool 'knife' .* has no stand pose"):
        standing_tool("knife")


@pytest.fixture(scope="module")
def sim():
    from pasta.sim import SimConfig, Simulator

    reg = get_plugins().tools
    tools = [reg.info(n).spec for n in ("spatula", "board", "gripper")]
    return Simulator(SimConfig(n_particles=3000), tools=tools)


def _settled(sim, boxes, seed):
    from pasta.demos.scene import scene_particles

    rng = np.random.default_rng(seed)
    sim.reset(scene_particles(boxes, 3000, rng)[0], seed=0)
    for _ in range(10):
        sim.step()
    return sim.observe().dough


@pytest.mark.sim
def test_lift_expert_sets_the_dough_down_on_the_board(sim):
    from pasta_skill_lift.tool import BOARD_HALF, BOARD_POSE, BOARD_TOP

    skill = get_plugins().skills.create("lift")
    rng = np.random.default_rng(3)
    dough = _settled(sim, skill.demo_scene(rng, sim.floor_y), 3)
    sim.set_tool_pose("board", BOARD_POSE)
    params = {"target_x": 0.28, "target_z": 0.52, "surface_y": BOARD_TOP}
    run = run_skill(sim, skill, skill.expert(params), np.arange(len(dough)), None,
                    approach=skill.expert_approach_pose(dough, params))
    for _ in range(20):  # the spatula is parked: the dough must stay on the board by itself
        sim.step()
    after = sim.observe().dough
    assert run.done
    assert np.percentile(after[:, 1], 1) > BOARD_TOP - 0.005  # resting on the board's top, not the floor
    assert np.abs(after[:, 0] - BOARD_POSE[0]).max() < BOARD_HALF[0]  # within the board
    assert np.linalg.norm(after[:, [0, 2]].mean(0) - [0.28, 0.52]) < 0.01


@pytest.mark.sim
def test_gather_expert_presses_three_lumps_into_one_piece(sim):
    skill = get_plugins().skills.create("gather")
    rng = np.random.default_rng(5)
    dough = _settled(sim, skill.demo_scene(rng, sim.floor_y), 5)
    assert decompose_labels(dough).max() + 1 == 3  # three entities before
    params = {"width": 0.065}
    run = run_skill(sim, skill, skill.expert(params), np.arange(len(dough)), None,
                    approach=skill.expert_approach_pose(dough, params))
    after = sim.observe().dough
    assert run.done
    assert decompose_labels(after).max() + 1 == 1
    from pasta_skill_gather.skill import closing_axis, span_along

    lo, hi = span_along(after, closing_axis(dough), 1.0)
    assert hi - lo < 0.1  # compact: the lumps spanned 0.19-0.25


@pytest.mark.sim
def test_lift_demonstrations_stand_the_board_and_end_on_it(tmp_path):
    """`Skill.demo_tools`: the demo machinery places the board the lift package asks for, so a lift
    demonstration ends with the dough on the board, as in the tasks (not lowered back onto the floor)."""
    from pasta.cli import main
    from pasta.demos.data import load_demos
    from pasta_skill_lift.tool import BOARD_TOP

    assert main(["demos", "skill=lift", "num=1", f"out={tmp_path}", "workers=0", "n_particles=2000",
                 "obs_points=400"]) == 0
    (demo,) = load_demos(tmp_path, ["lift"])
    assert demo.dough[0][:, 1].min() < 0.03  # starts on the floor
    assert demo.after[:, 1].min() > BOARD_TOP - 0.005  # ends resting on the board's top
