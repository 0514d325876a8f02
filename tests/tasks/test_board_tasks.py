"""The board tasks (lift_spread, gather_move): their goals end on the board; the oracle solves a config."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core.decompose import decompose_labels
from pasta.tasks import get_task

pytestmark = pytest.mark.sim


@pytest.mark.parametrize("name", ["lift_spread", "gather_move"])
def test_goal_rests_on_the_board(name):
    from pasta_skill_lift.tool import BOARD_TOP

    inst = get_task(name).instance(1000)  # the first fixed test config (cached by the task contract run)
    goal = inst.goal
    assert decompose_labels(goal).max() + 1 == 1
    assert np.percentile(goal[:, 1], 1) > BOARD_TOP - 0.005
    assert np.percentile(inst.init_points[:, 1], 1) < 0.03  # it started on the floor
    tools = list(inst.init.tool_names)
    assert "board" in tools  # the board's pose is part of the initial state


def test_lift_spread_rolls_the_dough_flat_on_the_board():
    inst = get_task("lift_spread").instance(1000)
    lifted = inst.steps[0].state[inst.obs_index]
    thick = lambda p: float(np.percentile(p[:, 1], 95) - np.percentile(p[:, 1], 1))  # noqa: E731
    assert thick(inst.goal) < 0.6 * thick(lifted)


def test_gather_move_starts_from_three_lumps():
    inst = get_task("gather_move").instance(1000)
    assert decompose_labels(inst.init_points).max() + 1 == 3
    assert inst.skeleton == ["gather", "lift"]


@pytest.mark.slow
@pytest.mark.parametrize("name", ["lift_spread", "gather_move"])
def test_oracle_solves_the_first_test_config(name):
    from pasta.tasks.oracle import run_oracle

    task = get_task(name)
    res = run_oracle(task, task.instance(1000))
    assert res.score.success, res.score


def test_lift_spread_success_needs_the_sheet_not_only_the_place():
    """The cube lifted onto the board but not rolled scores near the threshold on the EMD alone (0.846-0.933
    on the fixed configs); the flattening term fails it, the goal itself passes."""
    task = get_task("lift_spread")
    inst = task.instance(1000)
    lifted = inst.steps[0].state[inst.obs_index]  # the expert's lift, before its roll
    assert task.score(lifted, inst).improvement > 0.85 and not task.score(lifted, inst).success
    assert task.score(inst.goal, inst).success
    assert task.key() == get_task("lift_spread", min_flattening=0.9).key()  # scoring only: same instances


def test_flattening_measures_thickness_progress():
    from pasta_tasks_board.tasks import flattening, thickness

    rng = np.random.default_rng(0)
    slab = lambda h: rng.random((2000, 3)) * [0.1, h, 0.1] + [0.3, 0.07, 0.5]  # noqa: E731
    cube, sheet, half = slab(0.06), slab(0.02), slab(0.04)
    assert thickness(cube) == pytest.approx(0.06, abs=0.002)
    assert flattening(cube, sheet, sheet) == pytest.approx(1.0, abs=0.05)
    assert flattening(cube, cube, sheet) == pytest.approx(0.0, abs=0.05)
    assert flattening(cube, half, sheet) == pytest.approx(0.5, abs=0.06)
