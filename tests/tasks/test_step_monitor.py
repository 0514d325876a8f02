"""The step monitor (GoalMonitor, the pasta.core.StepMonitor contract): whether a step starts, when it ends
and whether it is retried, for every controller, through run_skill (no simulator needed)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from pasta.config import ExecuteConfig, PerceptionConfig
from pasta.core import Controller, InputError, PluginValidationError, SkillObservation, Stop, ToolPose, stop_reason
from pasta.core.errors import ConfigError
from pasta.execute.executor import step_monitor
from pasta.tasks.step import GoalMonitor, run_skill


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
    """Pushes left at full speed and never says it stops (a done head that stays low); watched, as a
    learned policy is."""

    watch = True

    def act(self, obs: SkillObservation):
        return np.array([-1.0]), None


class _TrustedLeft(_AlwaysLeft):
    watch = False


_SKILL = SimpleNamespace(name="shove", tool="paddle", max_steps=40,
                         approach_pose=lambda piece, goal, scene=None: ToolPose((0.7, 0.05, 0.5)),
                         park_pose=lambda: ToolPose((0.9, 0.3, 0.9)))


def _goal(sim: _PushSim, dx: float) -> np.ndarray:
    return sim.dough + np.float32([dx, 0.0, 0.0])


def test_a_controller_says_done_or_cap_and_nothing_else():
    assert stop_reason(None) is None and stop_reason(False) is None
    assert stop_reason(True) is Stop.DONE and stop_reason("cap") is Stop.CAP and stop_reason(Stop.DONE) is Stop.DONE
    with pytest.raises(PluginValidationError, match="may only say 'done' or 'cap'"):
        stop_reason(Stop.REGRESSED)
    with pytest.raises(PluginValidationError, match="stop='maybe'"):
        stop_reason("maybe")


def test_stops_a_watched_push_that_runs_past_its_goal():
    sim = _PushSim()
    start_x = float(sim.dough[:, 0].mean())
    goal = _goal(sim, -0.15)  # 15 env steps away
    run = run_skill(sim, _SKILL, _AlwaysLeft(), np.arange(300), goal, idle_steps=0)
    assert run.ended is Stop.REGRESSED and run.done and run.steps < _SKILL.max_steps
    overshoot = (start_x - 0.15) - float(sim.dough[:, 0].mean())
    assert 0.0 < overshoot <= 0.05, overshoot  # stopped a few steps past the goal, not 25 steps past it
    # a trusted controller runs on to the skill's limit, and the monitor says so
    sim2 = _PushSim()
    run2 = run_skill(sim2, _SKILL, _TrustedLeft(), np.arange(300), _goal(sim2, -0.15), idle_steps=0)
    assert run2.ended is Stop.LIMIT and run2.steps == _SKILL.max_steps and not run2.done


def test_never_stops_a_watched_step_before_it_made_progress_unless_it_started_at_its_goal():
    sim = _PushSim()
    run = run_skill(sim, _SKILL, _AlwaysLeft(), np.arange(300), _goal(sim, +0.15), idle_steps=0)
    assert run.ended is Stop.LIMIT and run.steps == _SKILL.max_steps  # moving away from the start: never watched
    sim2 = _PushSim()
    run2 = run_skill(sim2, _SKILL, _AlwaysLeft(), np.arange(300), _goal(sim2, 0.0), idle_steps=0,
                     monitor=GoalMonitor(near=1e-3))
    assert run2.ended is Stop.REGRESSED and run2.steps == 3  # at its goal already: moving away counts at once


def test_without_a_goal_nothing_is_watched():
    run = run_skill(_PushSim(), _SKILL, _AlwaysLeft(), np.arange(300), None, idle_steps=0, max_steps=5)
    assert run.ended is Stop.LIMIT and run.steps == 5


def _measure(monitor: GoalMonitor, goal: np.ndarray, distances: list[float], said=None) -> list:
    """Feed ``monitor`` pieces at those x-offsets from ``goal`` (Chamfer 2 d^2 on a 10-point line)."""
    return [monitor.should_stop(goal + np.float32([d, 0, 0]), said, i + 1) for i, d in enumerate(distances)]


def test_the_watch_counts_consecutive_steps_above_the_rise():
    goal = np.zeros((10, 3), np.float32)
    monitor = GoalMonitor(rise=0.5, patience=2, progress=0.5, near=0.0)
    monitor.begin(goal + np.float32([1.0, 0, 0]), goal, limit=100, watch=True)
    # progress to 0.1 (best 0.02), one step above, back at the best (the count restarts), then two in a row
    assert _measure(monitor, goal, [0.1, 0.2, 0.1, 0.2, 0.2]) == [None, None, None, None, Stop.REGRESSED]
    with pytest.raises(InputError, match="rise > 0"):
        GoalMonitor(rise=0.0)
    with pytest.raises(InputError, match="near >= 0"):
        GoalMonitor(near=-1.0)


def test_progress_sets_how_close_a_step_must_come_before_it_is_watched():
    goal = np.zeros((10, 3), np.float32)
    path = [0.9, 0.8, 1.0, 1.0, 1.0]  # at best 0.64 of the starting distance, then back to it
    halfway, closer = GoalMonitor(patience=3, progress=0.5, near=0.0), GoalMonitor(patience=3, progress=1.0, near=0.0)
    for m in (halfway, closer):
        m.begin(goal + np.float32([1.0, 0, 0]), goal, limit=100, watch=True)
    assert _measure(halfway, goal, path) == [None] * 5  # never came halfway: never watched
    assert _measure(closer, goal, path) == [None, None, None, None, Stop.REGRESSED]


def test_a_piece_near_its_goal_that_its_skill_calls_unfinished_may_first_move_away():
    """Within ``near`` of the goal a step counts as having made progress from the start, so moving away from its
    best ends it; a piece its skill calls unfinished (a cube to be rolled into a sheet) is watched against where
    the step found it instead."""
    goal = np.zeros((10, 3), np.float32)
    # starts at Chamfer 2 * 0.02^2 = 8e-4, closes in to 4.5e-4, moves away to 9.7e-4 (above 1.5x the best, below
    # 1.5x the start), closes in again
    path = [0.015, 0.022, 0.022, 0.022, 0.01, 0.005]
    results = {}
    for unfinished in (None, lambda piece: True):
        m = GoalMonitor(patience=3, near=0.001)
        m.begin(goal + np.float32([0.02, 0, 0]), goal, limit=100, watch=True, unfinished=unfinished)
        results[unfinished is not None] = _measure(m, goal, path)
    assert results[False][3] is Stop.REGRESSED
    assert results[True] == [None] * 6


def test_a_piece_its_skill_calls_unfinished_is_stopped_once_farther_than_it_started():
    """A pass may leave an unfinished piece farther than its best, not farther than the step found it: above
    ``(1 + rise)`` times the starting distance for ``patience`` env steps ends the step, unfinished or not."""
    goal = np.zeros((10, 3), np.float32)
    m = GoalMonitor(rise=0.5, patience=3, near=0.001)
    m.begin(goal + np.float32([0.01, 0, 0]), goal, limit=100, watch=True, unfinished=lambda piece: True)  # 2e-4
    # 1.8e-4 (its best), 3.9e-4 and 2.9e-4 (above the best's band, within the start's), then 3.9e-4 three times
    assert _measure(m, goal, [0.0095, 0.014, 0.012, 0.014, 0.014, 0.014]) == [None] * 5 + [Stop.REGRESSED]


def test_a_piece_its_skill_calls_unfinished_is_not_stopped_as_regressed():
    """A roll's pass leaves the dough lopsided (farther from the goal) until the next pass: while the skill says the
    piece still needs it (thicker than the goal), moving away from its best (not past where it started) does not
    end the step; once it is finished, it does."""
    goal = np.zeros((10, 3), np.float32)
    path = [0.1, 0.2, 0.2, 0.2, 0.1, 0.2, 0.2, 0.2]
    thick = {"now": True}
    m = GoalMonitor(rise=0.5, patience=3, progress=0.5, near=0.0)
    m.begin(goal + np.float32([1.0, 0, 0]), goal, limit=100, watch=True, unfinished=lambda piece: thick["now"])
    assert _measure(m, goal, path[:4]) == [None] * 4
    thick["now"] = False
    assert _measure(m, goal, path[4:]) == [None, None, None, Stop.REGRESSED]


def test_a_piece_its_skill_no_longer_calls_unfinished_counts_as_starting_there():
    """The `near` test of a piece the skill called unfinished at the start waits for the first env step it no
    longer does: within ``near`` of the goal then, moving away ends the step (a learned roll that goes on rolling
    a sheet already as thin as its goal); farther than ``near`` then, only real progress counts, as before."""
    goal = np.zeros((10, 3), np.float32)
    closes_in = [0.03, 0.015]  # Chamfer 1.8e-3, 4.5e-4: still unfinished
    then = [0.015, 0.03, 0.03, 0.03]  # within near (1e-3), then moves away (still within 1.5x the start, 3.2e-3)
    for finished, expected in ((True, [None, None, None, Stop.REGRESSED]), (False, [None] * 4)):
        thick = {"now": True}
        m = GoalMonitor(rise=0.5, patience=3, progress=0.01, near=0.001)  # progress: only `near` can count
        m.begin(goal + np.float32([0.04, 0, 0]), goal, limit=100, watch=True, unfinished=lambda piece: thick["now"])
        assert _measure(m, goal, closes_in) == [None, None]
        thick["now"] = not finished
        assert _measure(m, goal, then) == expected, finished
    # no longer unfinished while still far from the goal: the start is there, not within near; no stop
    m = GoalMonitor(rise=0.5, patience=3, progress=0.01, near=0.001)
    m.begin(goal + np.float32([0.04, 0, 0]), goal, limit=100, watch=True, unfinished=lambda piece: False)
    assert _measure(m, goal, [0.03, 0.05, 0.05, 0.05]) == [None] * 4


class _CappedLeft(Controller):
    """Pushes left at full speed and says it is at its cap after ``cap`` actions, as a learned policy does at
    its ``max_steps``."""

    watch = True

    def __init__(self, cap: int) -> None:
        self.cap, self.taken = cap, 0

    def act(self, obs: SkillObservation):
        self.taken += 1
        return np.array([-1.0]), Stop.CAP if self.taken >= self.cap else None


def test_overrun_runs_past_the_cap_only_while_the_piece_closes_on_its_goal():
    goal_dx = -0.15  # 15 env steps away; the controller's cap is 10
    sim = _PushSim()
    run = run_skill(sim, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim, goal_dx), idle_steps=0,
                    monitor=GoalMonitor(overrun=20))
    # on to the goal (15 steps) and one step past it, where the distance first grows: then it stops at its cap
    assert run.ended is Stop.CAP and run.done and run.steps == 16, run.steps
    # without overrun the cap ends it 5 steps short
    sim0 = _PushSim()
    assert run_skill(sim0, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim0, goal_dx), idle_steps=0,
                     monitor=GoalMonitor(overrun=0)).steps == 10
    # overrun is a budget: at most that many steps past the cap
    sim2 = _PushSim()
    assert run_skill(sim2, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim2, goal_dx), idle_steps=0,
                     monitor=GoalMonitor(overrun=3)).steps == 13
    # the skill's own step limit still ends it, and the step counts as ended at the cap (no retry)
    sim4 = _PushSim()
    run4 = run_skill(sim4, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim4, -0.5), idle_steps=0,
                     monitor=GoalMonitor(overrun=100))
    assert run4.steps == _SKILL.max_steps and run4.ended is Stop.CAP and run4.done
    # a step moving away from its goal at the cap is not continued
    sim3 = _PushSim()
    assert run_skill(sim3, _SKILL, _CappedLeft(10), np.arange(300), _goal(sim3, +0.15), idle_steps=0,
                     monitor=GoalMonitor(overrun=20)).steps == 10


def test_overrun_leaves_a_done_head_alone():
    class HeadDone(_CappedLeft):  # done by its own head, not by its cap
        def act(self, obs):
            action, said = super().act(obs)
            return action, Stop.DONE if said else None

    sim = _PushSim()
    run = run_skill(sim, _SKILL, HeadDone(10), np.arange(300), _goal(sim, -0.15), idle_steps=0,
                    monitor=GoalMonitor(overrun=20))
    assert run.steps == 10 and run.ended is Stop.DONE


def test_should_run_skips_only_watched_steps_that_keep_the_count_and_are_at_their_goal():
    goal = np.zeros((10, 3), np.float32)
    monitor = GoalMonitor(at_goal=5e-4)
    near = goal + np.float32([0.01, 0, 0])  # Chamfer 2e-4: at its goal
    real = goal + np.float32([0.02, 0, 0])  # Chamfer 8e-4: a small but real change to make
    assert monitor.should_run(near, goal, keeps_count=True, watch=True) is Stop.AT_GOAL
    assert monitor.should_run(real, goal, keeps_count=True, watch=True) is None
    assert monitor.should_run(near, goal, keeps_count=False, watch=True) is None  # a cut is never skipped
    assert monitor.should_run(near, goal, keeps_count=True, watch=False) is None  # a trusted controller runs
    assert GoalMonitor(at_goal=0.0).should_run(goal, goal, keeps_count=True, watch=True) is None  # 0: never


def test_a_skill_says_how_close_is_at_its_goal():
    from pasta.plugins import get_plugins

    goal = np.zeros((10, 3), np.float32)
    real = goal + np.float32([0.02, 0, 0])  # Chamfer 8e-4
    monitor = GoalMonitor(at_goal=5e-4)
    assert monitor.should_run(real, goal, keeps_count=True, watch=True, at_goal=None) is None  # the monitor's
    assert monitor.should_run(real, goal, keeps_count=True, watch=True, at_goal=1e-3) is Stop.AT_GOAL
    skills = get_plugins().skills
    roll = skills.create("roll")
    assert roll.at_goal == 1e-3  # a learned roll of a rolled piece spreads it again
    assert skills.create("push").at_goal is None  # the others: perception.unchanged_threshold
    # ...but a cube is not at the goal of the sheet it must become, however close by Chamfer
    rng = np.random.default_rng(0)
    cube = rng.uniform(0, 0.06, (800, 3)) + (0.27, 0.07, 0.47)
    sheet = rng.uniform(0, 1, (800, 3)) * (0.17, 0.018, 0.075) + (0.215, 0.07, 0.4625)
    rolled = sheet * (1, 1.1, 1) - (0, 0.007, 0)  # 10 % thicker: a roll would only spread it
    assert roll.unfinished(cube, sheet) and not roll.unfinished(rolled, sheet) and not roll.unfinished(sheet, sheet)
    assert not skills.create("push").unfinished(cube, sheet)  # the default: the distance decides


def test_retries_a_step_that_hit_the_limit_or_left_too_few_pieces():
    monitor = GoalMonitor()
    assert monitor.should_retry(2, 2, Stop.LIMIT) and monitor.should_retry(1, 2, Stop.DONE)
    assert not monitor.should_retry(2, 2, Stop.DONE) and not monitor.should_retry(2, 2, Stop.CAP)
    assert not monitor.should_retry(3, 2, Stop.REGRESSED)


def test_execute_settings_build_the_monitor():
    monitor = step_monitor(ExecuteConfig(regress_rise=0.25, regress_near=0.002, overrun=25),
                           PerceptionConfig(unchanged_threshold=3e-4))
    assert (monitor.rise, monitor.near, monitor.overrun, monitor.at_goal) == (0.25, 0.002, 25, 3e-4)
    for bad, key in (({"regress_rise": -1.0}, "regress_rise"), ({"regress_near": float("nan")}, "regress_near"),
                     ({"overrun": -1}, "overrun"), ({"controller": "magic"}, "controller"), ({"goal": "guessed"}, "goal")):
        with pytest.raises(ConfigError, match=f"execute.{key}="):
            ExecuteConfig(**bad)
