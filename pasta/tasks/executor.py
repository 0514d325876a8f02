"""Execute one skill step in the simulator: approach pose -> controller loop -> idle steps -> park.

:func:`run_skill` is the one place where a skill meets the simulator; the task generators (experts),
the oracle (heuristic controllers), demonstration recording and the plan executor (learned policies)
all go through it. The attended piece is tracked by particle identity: ``piece`` selects points of the
observed cloud (the simulator observes a fixed particle subset), and every env step the controller
sees the current positions of exactly those points.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pasta.core import Controller, InputError, Skill, SkillObservation, ToolPose
from pasta.core.metrics import chamfer

__all__ = ["RegressionStop", "SkillRun", "Trajectory", "piece_indices", "run_skill", "skill_observation"]


@dataclass
class Trajectory:
    """What :func:`run_skill` recorded (``record=True``): ``T`` controller steps.

    dough: ``(T+1, P, 3)`` float32 observed dough before each step and after the last;
    tool_points: ``(T+1, Tp, 3)``; tool_pose: ``(T+1, 7)``; action: ``(T, A)`` float32.
    """

    dough: list[np.ndarray] = field(default_factory=list)
    tool_points: list[np.ndarray] = field(default_factory=list)
    tool_pose: list[np.ndarray] = field(default_factory=list)
    action: list[np.ndarray] = field(default_factory=list)

    def add_obs(self, obs: Any, tool: str) -> None:
        self.dough.append(np.asarray(obs.dough, np.float32))
        self.tool_points.append(np.asarray(obs.tool_points[tool], np.float32))
        self.tool_pose.append(np.asarray(obs.tool_poses[tool], np.float32))

    def arrays(self, action_dim: int) -> dict[str, np.ndarray]:
        act = np.stack(self.action).astype(np.float32) if self.action else np.zeros((0, action_dim), np.float32)
        return {
            "dough": np.stack(self.dough).astype(np.float32),
            "tool_points": np.stack(self.tool_points).astype(np.float32),
            "tool_pose": np.stack(self.tool_pose).astype(np.float32),
            "action": act,
        }


@dataclass
class SkillRun:
    """Outcome of one skill step.

    Attributes:
        skill: skill name.
        steps: controller env steps taken (idle steps not counted).
        done: the controller reported done (``False``: it hit ``max_steps``).
        approach: the tool pose the step started from.
        wall_s: wall-clock seconds of the whole step (approach to park).
        trajectory: the recorded steps, when asked for.
        stopped: the step was ended by a :class:`RegressionStop` (``done`` is then ``True`` too).
    """

    skill: str
    steps: int
    done: bool
    approach: ToolPose
    wall_s: float
    trajectory: Trajectory | None = None
    stopped: bool = False


@dataclass
class RegressionStop:
    """Ends a controller's step once its piece has moved away from the sub-goal again.

    A closed-loop check for controllers whose own stop is unreliable: a learned push whose done head
    stays low pushes on past its goal, and pushing cannot pull the piece back. Every env step the
    Chamfer distance ``d`` between the attended piece and the step's goal is measured (on at most
    ``points`` fixed points of each); once the step has made real progress (its best distance is below
    ``progress`` times the starting one) and ``d`` has stayed above ``best * (1 + rise)`` for ``patience``
    steps in a row, the step ends as done. A step that has not made progress yet (a knife still
    descending) is never stopped, unless its piece started within ``near`` (Chamfer) of the goal: that
    piece is at its goal already (a plan that rolls a rolled piece once more), so moving away counts.

    ``overrun``: a controller that ended only because it reached its own step cap (a learned policy's
    ``max_steps``; it says so with ``at_cap``) runs on for at most this many env steps while every one of
    them brings the piece closer to the goal than it has been (:meth:`run_on`). The caps were chosen on
    single-skill configs; a cut that must carry its piece further than any demonstration did is still
    closing on its goal when its cap ends it (docs/policies.md). 0 (the default) keeps the caps.

    Use: ``start(piece (K, 3), goal (G, 3))`` before the first action, then ``update(piece) -> stop``
    after every env step (``run_on(piece) -> go on`` instead, once the controller is at its cap). One
    instance serves one step at a time (``start`` resets it). :meth:`at_goal` says whether a piece starts
    within ``near`` of its goal.
    """

    rise: float = 0.5
    patience: int = 3
    progress: float = 0.5
    points: int = 256
    near: float = 0.0
    overrun: int = 0

    def __post_init__(self) -> None:
        ok = (self.rise > 0 and self.patience >= 1 and 0 < self.progress <= 1 and self.points >= 1
              and self.near >= 0 and self.overrun >= 0)
        if not ok:
            raise InputError("RegressionStop needs rise > 0, patience >= 1, progress in (0, 1], points >= 1, "
                             f"near >= 0, overrun >= 0; got {self}")
        self._goal: np.ndarray | None = None

    def _subset(self, cloud: np.ndarray) -> np.ndarray:
        cloud = np.asarray(cloud, np.float32)
        if len(cloud) <= self.points:
            return cloud
        return cloud[np.linspace(0, len(cloud) - 1, self.points).astype(np.int64)]  # same particles every step

    def _distance(self, piece: np.ndarray) -> float:
        return float(chamfer(self._subset(piece), self._goal))

    def start(self, piece: np.ndarray, goal: np.ndarray) -> None:
        self._goal = self._subset(goal)
        self.initial = self.best = self._distance(piece)
        self.above = 0
        self.closer = False  # the last update set a new best distance
        self.overran = 0  # env steps run past the controller's cap

    def at_goal(self, piece: np.ndarray, goal: np.ndarray) -> bool:
        """Whether ``piece (K, 3)`` lies within ``near`` (Chamfer, the measure of :meth:`update`) of ``goal (G, 3)``."""
        return self.near > 0 and float(chamfer(self._subset(piece), self._subset(goal))) < self.near

    def update(self, piece: np.ndarray) -> bool:
        if self._goal is None:
            raise InputError("RegressionStop.update before start")
        d = self._distance(piece)
        self.closer = d < self.best
        self.best = min(self.best, d)
        progressed = self.best < self.progress * self.initial or self.initial < self.near
        self.above = self.above + 1 if progressed and d > self.best * (1.0 + self.rise) else 0
        return self.above >= self.patience

    def run_on(self, piece: np.ndarray) -> bool:
        """After an env step the controller took at its cap: whether the step may go on past the cap
        (``overrun`` not used up, and that step brought ``piece`` closer than ever)."""
        if self.overran >= self.overrun:
            return False
        self.overran += 1
        return not self.update(piece) and self.closer


def piece_indices(piece: Any, num_points: int) -> np.ndarray:
    """Indices ``(K,)`` into the observed cloud from a boolean mask ``(P,)`` or an index array."""
    arr = np.asarray(piece)
    if arr.dtype == bool:
        if arr.shape != (num_points,):
            raise InputError(f"piece mask must have shape ({num_points},), got {arr.shape}")
        idx = np.flatnonzero(arr)
    else:
        idx = arr.astype(np.int64).reshape(-1)
        if idx.size and (idx.min() < 0 or idx.max() >= num_points):
            raise InputError(f"piece indices must lie in [0, {num_points}), got [{idx.min()}, {idx.max()}]")
    if idx.size == 0:
        raise InputError("the attended piece is empty (no observed points selected)")
    return idx


def skill_observation(obs: Any, tool: str, idx: np.ndarray, goal: np.ndarray | None) -> SkillObservation:
    """The controller's view of a simulator observation: attended piece ``idx``, goal, tool, scene."""
    return SkillObservation(
        piece=obs.dough[idx],
        goal=None if goal is None else np.asarray(goal, np.float32),
        tool_points=np.asarray(obs.tool_points[tool], np.float32),
        tool_pose=np.asarray(obs.tool_poses[tool], np.float32),
        scene=obs.dough,
    )


def run_skill(
    sim: Any,
    skill: Skill,
    controller: Controller,
    piece: Any,
    goal_points: np.ndarray | None,
    *,
    max_steps: int | None = None,
    idle_steps: int = 10,
    approach: ToolPose | None = None,
    park: bool = True,
    record: bool = False,
    stop: RegressionStop | None = None,
) -> SkillRun:
    """Run one skill step in ``sim`` and return what happened.

    Args:
        sim: a :class:`pasta.sim.Simulator` with a scene loaded.
        skill: the skill (its ``tool`` is the one driven).
        controller: expert, heuristic controller or learned policy of that skill.
        piece: the attended piece, as a boolean mask ``(P,)`` or indices into the observed cloud.
        goal_points: ``(G, 3)`` sub-goal of the step (all produced pieces), or ``None`` (experts).
        max_steps: controller step limit (default: the skill's ``max_steps`` or 50).
        idle_steps: zero-action env steps after the controller stops (the dough settles).
        approach: start pose of the tool (default: the controller's ``approach_pose(piece, goal, scene=...)``
            when it has one and it returns a pose, e.g. a learned policy's reset pose, else
            ``skill.approach_pose(piece, goal, scene=...)``).
        park: teleport the tool to ``skill.park_pose()`` at the end.
        record: keep the observations and actions (:class:`Trajectory`).
        stop: end the step early once the piece moves away from ``goal_points`` again
            (:class:`RegressionStop`; needs a goal).

    The loop: the controller sees the observation and returns ``(action, done)``; a done with an
    all-zero action ends the step without stepping, a done with a non-zero action is applied and then
    ends the step (the last action of a demonstration).
    """
    t0 = time.perf_counter()
    tool = skill.tool
    obs = sim.observe()
    idx = piece_indices(piece, len(obs.dough))
    if max_steps is None:
        max_steps = int(getattr(skill, "max_steps", 50))
    if approach is None and callable(getattr(controller, "approach_pose", None)):
        # a controller with its own (learned) start pose; None falls back to the skill's
        approach = controller.approach_pose(obs.dough[idx], goal_points, scene=obs.dough)
    if approach is None:
        try:
            approach = skill.approach_pose(obs.dough[idx], goal_points, scene=obs.dough)
        except TypeError:  # a skill whose approach_pose has the two-argument contract signature
            approach = skill.approach_pose(obs.dough[idx], goal_points)
    sim.set_tool_pose(tool, approach.position, yaw=approach.yaw)
    obs = sim.observe()
    traj = Trajectory() if record else None
    view = skill_observation(obs, tool, idx, goal_points)
    controller.reset(view)
    steps, done, stopped, capped = 0, False, False, False
    if stop is not None and goal_points is not None:
        stop.start(view.piece, view.goal)
    else:
        stop = None
    while steps < max_steps:
        action, done = controller.act(view)
        action = np.clip(np.asarray(action, np.float32).reshape(-1), -1.0, 1.0)
        if done and not np.any(action):
            break
        if traj is not None:
            traj.add_obs(obs, tool)
            traj.action.append(action)
        sim.step({tool: action})
        steps += 1
        obs = sim.observe()
        view = skill_observation(obs, tool, idx, goal_points)
        if done:
            if stop is None or not getattr(controller, "at_cap", False) or not stop.run_on(view.piece):
                break
            done, capped = False, True  # past the controller's cap while the piece still closes on its goal
            continue
        if stop is not None and stop.update(view.piece):
            done = stopped = True
            break
    done = done or capped  # a controller run past its own cap had reported done there
    if traj is not None:
        traj.add_obs(obs, tool)
    for _ in range(max(0, idle_steps)):
        sim.step()
    if park:
        pose = skill.park_pose()
        sim.set_tool_pose(tool, pose.position, yaw=pose.yaw)
    return SkillRun(skill.name, steps, bool(done), approach, time.perf_counter() - t0, traj, stopped)
