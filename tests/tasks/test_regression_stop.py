"""RegressionStop: a step ends once its piece moves away from the sub-goal again (no simulator needed)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pasta.core import Controller, InputError, SkillObservation, ToolPose
from pasta.core.errors import ConfigError
from pasta.execute.executor import ExecuteConfig
from pasta.tasks.executor import RegressionStop, run_skill


class _PushSim:
    """Stand-in simulator: a tool that moves the whole dough by ``0.01 * action[0]`` along x per env step."""

    def __init__(self) -> None:
        rng = np.random.default_rng(0)
        self.dough = (rng.random((300, 3)) * [0.1, 0.05, 0.08] + [0.5, 0.0, 0.45]).astype(np.float32)
        self.pose = np.zeros(3)

    def observe(self):
        p = np.r_[self.pose, 1, 0, 0, 0].astype(np.float32)
        return SimpleNamespace(dough=self.dough, tool_poses={"paddle": p},
                               tool_points={"paddle": np.tile(self.pose, (4, 1)).astype(np.float32)})

    def set_tool_pose(self, name, position, yaw=0.0):
        self.pose = np.asarray(position, float)

    def step(self, actions=None):
        if actions:
            self.dough = self.dough + np.float32([0.01 * float(actions["paddle"][0]), 0.0, 0.0])


class _AlwaysLeft(Controller):
    """Pushes left at full speed and never reports done (a done head that stays low)."""

    def act(self, obs: SkillObservation):
        return np.array([-1.0]), False


_SKILL = SimpleNamespace(name="shove", tool="paddle", max_steps=40,
                         approach_pose=lambda piece, goal, scene=None: ToolPose((0.7, 0.05, 0.5)),
                         park_pose=lambda: ToolPose((0.9, 0.3, 0.9)))


def _goal(sim: _PushSim, dx: float) -> np.ndarray:
    return sim.dough + np.float32([dx, 0.0, 0.0])


def test_stops_a_push_that_runs_past_its_goal():
    sim = _PushSim()
    start_x = float(sim.dough[:, 0].mean())
    goal = _goal(sim, -0.15)  # 15 env steps away
    run = run_skill(sim, _SKILL, _AlwaysLeft(), np.arange(300), goal, idle_steps=0, stop=RegressionStop())
    assert run.stopped and run.done and run.steps < _SKILL.max_steps
    overshoot = (start_x - 0.15) - float(sim.dough[:, 0].mean())
    assert 0.0 < overshoot <= 0.05, overshoot  # stopped a few steps past the goal, not 25 steps past it
    # without the stop the controller pushes to its step limit, 25 cm past the goal
    sim2 = _PushSim()
    run2 = run_skill(sim2, _SKILL, _AlwaysLeft(), np.arange(300), _goal(sim2, -0.15), idle_steps=0)
    assert not run2.stopped and not run2.done and run2.steps == _SKILL.max_steps


def test_never_stops_a_step_that_has_made_no_progress():
    sim = _PushSim()
    goal = _goal(sim, +0.15)  # the goal is to the right: pushing left only moves away from it
    run = run_skill(sim, _SKILL, _AlwaysLeft(), np.arange(300), goal, idle_steps=0, stop=RegressionStop())
    assert not run.stopped and run.steps == _SKILL.max_steps


def test_a_piece_that_starts_at_its_goal_is_stopped_once_it_moves_away():
    sim = _PushSim()
    goal = _goal(sim, 0.0)  # already there: a plan that runs a step on a piece a step before finished
    run = run_skill(sim, _SKILL, _AlwaysLeft(), np.arange(300), goal, idle_steps=0, stop=RegressionStop(near=1e-3))
    assert run.stopped and run.done and run.steps <= 5, run.steps
    # without `near` the step never made progress, so it runs to its limit
    sim2 = _PushSim()
    run2 = run_skill(sim2, _SKILL, _AlwaysLeft(), np.arange(300), _goal(sim2, 0.0), idle_steps=0, stop=RegressionStop())
    assert not run2.stopped and run2.steps == _SKILL.max_steps
    # a piece that starts farther than `near` from its goal is still left alone until it has made progress
    sim3 = _PushSim()
    run3 = run_skill(sim3, _SKILL, _AlwaysLeft(), np.arange(300), _goal(sim3, +0.15), idle_steps=0,
                     stop=RegressionStop(near=1e-3))
    assert not run3.stopped and run3.steps == _SKILL.max_steps


def test_without_a_goal_the_stop_is_ignored():
    run = run_skill(_PushSim(), _SKILL, _AlwaysLeft(), np.arange(300), None, idle_steps=0, max_steps=5,
                    stop=RegressionStop())
    assert not run.stopped and run.steps == 5


def test_stop_counts_consecutive_steps_above_the_rise():
    stop = RegressionStop(rise=0.5, patience=2, progress=0.5)
    goal = np.zeros((10, 3), np.float32)
    piece = lambda d: goal + np.float32([d, 0, 0])  # Chamfer distance 2 d^2
    stop.start(piece(1.0), goal)
    assert not stop.update(piece(0.1))  # progress: best 0.02
    assert not stop.update(piece(0.2))  # 0.08 > 0.03: one step above
    assert not stop.update(piece(0.1))  # back at the best: the count restarts
    assert not stop.update(piece(0.2))
    assert stop.update(piece(0.2))      # two in a row
    with pytest.raises(InputError, match="before start"):
        RegressionStop().update(goal)
    with pytest.raises(InputError, match="rise > 0"):
        RegressionStop(rise=0.0)


def test_progress_sets_how_close_a_step_must_come_before_it_is_watched():
    goal = np.zeros((10, 3), np.float32)
    piece = lambda d: goal + np.float32([d, 0, 0])  # Chamfer distance 2 d^2
    path = [0.9, 0.8, 1.0, 1.0, 1.0]  # at best 0.64 of the starting distance, then back to it
    halfway, closer = RegressionStop(patience=3, progress=0.5), RegressionStop(patience=3, progress=1.0)
    halfway.start(piece(1.0), goal)
    closer.start(piece(1.0), goal)
    assert not any(halfway.update(piece(d)) for d in path)  # never came halfway: never watched
    assert [closer.update(piece(d)) for d in path] == [False, False, False, False, True]


def test_execute_config_chooses_which_controllers_are_watched():
    assert ExecuteConfig(controller="learned").regression_stop() is not None
    assert ExecuteConfig(controller="heuristic").regression_stop() is None
    assert ExecuteConfig(controller="heuristic", regress_stop="all").regression_stop() is not None
    assert ExecuteConfig(controller="learned", regress_stop="off").regression_stop() is None
    assert ExecuteConfig(controller="learned", regress_stop="False").regression_stop() is None  # `off` via YAML
    assert ExecuteConfig(controller="learned", regress_rise=0.25).regression_stop().rise == 0.25
    with pytest.raises(ConfigError, match="regress_stop"):
        ExecuteConfig(regress_stop="sometimes")
    with pytest.raises(ConfigError, match="regress_rise"):
        ExecuteConfig(regress_rise=-1.0)
    assert ExecuteConfig(controller="learned", regress_near=0.002).regression_stop().near == 0.002
    with pytest.raises(ConfigError, match="regress_near"):
        ExecuteConfig(regress_near=float("nan"))
    assert ExecuteConfig(controller="learned").regression_stop().progress == 0.5
    assert ExecuteConfig(controller="learned", regress_progress=1.0).regression_stop().progress == 1.0
    for bad in (0.0, 1.5, float("nan")):
        with pytest.raises(ConfigError, match="regress_progress"):
            ExecuteConfig(regress_progress=bad)
    with pytest.raises(InputError, match="near >= 0"):
        RegressionStop(near=-1.0)


class _CappedLeft(Controller):
    """Pushes left at full speed and reports done after ``cap`` actions, saying it was its cap (``at_cap``),
    as a learned policy does at its ``max_steps``."""

    def __init__(self, cap: int) -> None:
        self.cap, self.taken, self.at_cap = cap, 0, False

    def act(self, obs: SkillObservation):
        self.taken += 1
        self.at_cap = self.taken >= self.cap
        return np.array([-1.0]), self.at_cap


def test_overrun_runs_past_the_cap_only_while_the_piece_closes_on_its_goal():
    goal_dx = -0.15  # 15 env steps away; the controller's cap is 10
    sim = _PushSim()
    run = run_skill(sim, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim, goal_dx), idle_steps=0,
                    stop=RegressionStop(overrun=20))
    # on to the goal (15 steps) and one step past it, where the distance first grows: then it stops
    assert run.done and run.steps == 16, run.steps
    # without overrun the cap ends it 5 steps short
    sim0 = _PushSim()
    assert run_skill(sim0, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim0, goal_dx), idle_steps=0,
                     stop=RegressionStop()).steps == 10
    # overrun is a budget: at most that many steps past the cap
    sim2 = _PushSim()
    assert run_skill(sim2, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim2, goal_dx), idle_steps=0,
                     stop=RegressionStop(overrun=3)).steps == 13
    # the skill's own step limit still ends it, and it counts as done (the controller said so at its cap)
    sim4 = _PushSim()
    run4 = run_skill(sim4, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim4, -0.5), idle_steps=0,
                     stop=RegressionStop(overrun=100))
    assert run4.steps == _SKILL.max_steps and run4.done
    # a step moving away from its goal at the cap is not continued
    sim3 = _PushSim()
    assert run_skill(sim3, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim3, +0.15), idle_steps=0,
                     stop=RegressionStop(overrun=20)).steps == 10


def test_overrun_leaves_a_done_head_alone():
    class HeadDone(_CappedLeft):  # done by its own head: no at_cap
        def act(self, obs):
            action, done = super().act(obs)
            self.at_cap = False
            return action, done

    sim = _PushSim()
    run = run_skill(sim, _SKILL, HeadDone(10), np.arange(300), _goal(sim, -0.15), idle_steps=0,
                    stop=RegressionStop(overrun=20))
    assert run.steps == 10


def test_at_goal_and_overrun_settings():
    goal = np.zeros((10, 3), np.float32)
    stop = RegressionStop(near=1e-3)
    assert stop.at_goal(goal + np.float32([0.01, 0, 0]), goal)  # Chamfer 2e-4
    assert not stop.at_goal(goal + np.float32([0.1, 0, 0]), goal)
    assert not RegressionStop().at_goal(goal, goal)  # near 0: never
    assert ExecuteConfig(controller="learned", overrun=25).regression_stop().overrun == 25
    with pytest.raises(ConfigError, match="overrun"):
        ExecuteConfig(overrun=-1)
    with pytest.raises(InputError, match="overrun >= 0"):
        RegressionStop(overrun=-2)
