"""Execute one skill step in the simulator: approach pose -> controller loop -> idle steps -> park.

:func:`run_skill` is the one place where a skill meets the simulator; the task generators (experts),
the oracle (heuristic controllers), demonstration recording and the plan executor (learned policies)
all go through it, and one step monitor (:class:`GoalMonitor`, the :class:`pasta.core.StepMonitor`
contract) decides for all of them when a step ends. The attended piece is tracked by particle identity: ``piece`` selects points of the
observed cloud (the simulator observes a fixed particle subset), and every env step the controller
sees the current positions of exactly those points.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pasta.core import Controller, InputError, Skill, SkillObservation, StepMonitor, Stop, ToolPose, stop_reason
from pasta.core.metrics import chamfer

__all__ = ["GBTO_ITERATIONS", "GBTO_STEPS", "GoalMonitor", "Replay", "SkillRun", "Trajectory", "approach_pose", "gbto_budget",
           "gbto_expert",
           "piece_indices", "run_skill", "skill_observation"]


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
        ended: why the step ended (:class:`~pasta.core.Stop`).
        approach: the tool pose the step started from.
        wall_s: wall-clock seconds of the whole step (approach to park).
        trajectory: the recorded steps, when asked for.
        path: ``(T+1, 3)`` the driven tool's centre from the approach pose to where its motion ended.
        end_poses: every tool's pose ``(7,)`` when the motion ended (before the idle steps and parking);
            ``end_apertures``: their apertures then (simulators that have apertures).
    """

    skill: str
    steps: int
    ended: Stop
    approach: ToolPose
    wall_s: float
    trajectory: Trajectory | None = None
    path: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))
    end_poses: dict[str, np.ndarray] = field(default_factory=dict)
    end_apertures: dict[str, float] = field(default_factory=dict)

    @property
    def done(self) -> bool:
        """The step ended as its controller or its monitor meant it to, not at the skill's step limit."""
        return self.ended is not Stop.LIMIT


@dataclass
class GoalMonitor(StepMonitor):
    """The step monitor of every skill step (:class:`pasta.core.StepMonitor`).

    A trusted controller (``watch=False``: scripted experts, heuristic controllers) runs until it says it
    stops or the skill's step limit. A watched one (``watch=True``: learned policies) is also measured
    every env step by the Chamfer distance ``d`` between its piece and the step's goal (on at most
    ``points`` fixed points of each), and:

    - is not started when its piece already lies within ``at_goal`` of the goal (or the skill's own
      :attr:`~pasta.core.Skill.at_goal`) and the step makes as many pieces as it takes (a plan that rolls a
      rolled piece once more; a cut is never skipped: to Chamfer a dough and its two halves a few millimetres
      apart are close);
    - is stopped (:attr:`~pasta.core.Stop.REGRESSED`) once it has made real progress (its best distance
      below ``progress`` times the starting one) and ``d`` has stayed above ``best * (1 + rise)`` for
      ``patience`` env steps in a row: pushing cannot pull a piece back, so a push that overshoots only
      gets worse. A piece that started within ``near`` of its goal counts as having made progress from
      the first step, so moving away from the goal ends the step at once. While the skill calls the piece
      unfinished (:meth:`~pasta.core.Skill.unfinished`) the band is around the starting distance instead of
      the best: a roll's passes leave the dough lopsided until the next pass evens it, and a cube lies within
      ``near`` of the sheet it must become, but a pass that leaves the piece farther from its goal than the
      step found it is not evening anything out (a learned roll of a sheet a few millimetres thicker than
      its goal piled and spread it: Chamfer 2e-4 -> 8e-3 over 60 steps). A piece the skill called
      unfinished at the start counts as starting at the first env step it no longer does (its best distance
      then, for the ``near`` test);
    - when it says it is at its own step cap (:attr:`~pasta.core.Stop.CAP`), runs on for at most
      ``overrun`` more env steps while every one of them brings the piece closer than it has been: the
      caps were chosen on single-skill configs, and a cut that must carry its piece further than any
      demonstration did is still closing on its goal when its cap ends it (docs/policies.md).

    A step is retried (:meth:`should_retry`) when it ended at the skill's step limit, or when fewer pieces
    are observed than a successful step leaves (a cut whose bottom layer still joins the halves).
    """

    rise: float = 0.5
    near: float = 0.001
    overrun: int = 40
    at_goal: float = 5e-4
    patience: int = 3
    progress: float = 0.5
    points: int = 256

    def __post_init__(self) -> None:
        ok = (self.rise > 0 and self.patience >= 1 and 0 < self.progress <= 1 and self.points >= 1
              and self.near >= 0 and self.at_goal >= 0 and self.overrun >= 0)
        if not ok:
            raise InputError("GoalMonitor needs rise > 0, patience >= 1, progress in (0, 1], points >= 1, "
                             f"near >= 0, at_goal >= 0, overrun >= 0; got {self}")
        self._goal: np.ndarray | None = None
        self._watch = False
        self._limit = 0
        self._start: float | None = None
        self._unfinished: Callable[[np.ndarray], bool] | None = None

    def _subset(self, cloud: np.ndarray) -> np.ndarray:
        cloud = np.asarray(cloud, np.float32)
        if len(cloud) <= self.points:
            return cloud
        return cloud[np.linspace(0, len(cloud) - 1, self.points).astype(np.int64)]  # same particles every step

    def distance(self, piece: np.ndarray, goal: np.ndarray) -> float:
        """The Chamfer distance the monitor measures, between ``piece (P, 3)`` and ``goal (G, 3)``."""
        return float(chamfer(self._subset(piece), self._subset(goal)))

    def should_run(self, piece: np.ndarray, goal: np.ndarray | None, *, keeps_count: bool,
                   watch: bool, at_goal: float | None = None) -> Stop | None:
        tolerance = self.at_goal if at_goal is None else float(at_goal)
        if (watch and keeps_count and goal is not None and len(piece) and tolerance > 0
                and self.distance(piece, goal) < tolerance):
            return Stop.AT_GOAL
        return None

    def begin(self, piece: np.ndarray, goal: np.ndarray | None, *, limit: int, watch: bool,
              unfinished: Callable[[np.ndarray], bool] | None = None) -> None:
        self._limit = int(limit)
        self._unfinished = unfinished if watch else None
        self._watch = bool(watch) and goal is not None
        self._goal = self._subset(goal) if self._watch and goal is not None else None
        self.initial = self.best = self._measure(piece) if self._watch else 0.0
        # where the piece counts as starting for the `near` test: now, or (unfinished now) the first env step
        # the skill no longer calls it unfinished (None until then)
        self._start = None if self._unfinished is not None and self._unfinished(piece) else self.initial
        self.above = 0  # env steps in a row above the regression band
        self.overran = 0  # env steps run past the controller's cap

    def _measure(self, piece: np.ndarray) -> float:
        return float(chamfer(self._subset(piece), self._goal))

    def _regressed(self, piece: np.ndarray) -> tuple[bool, bool]:
        """Measure ``piece``: ``(regressed, closer than ever)``."""
        d = self._measure(piece)
        closer = d < self.best
        self.best = min(self.best, d)
        unfinished = self._unfinished is not None and self._unfinished(piece)
        if self._start is None and not unfinished:
            self._start = self.best
        if unfinished:  # lopsided passes may leave the best behind, not the start
            moved_away = d > self.initial * (1.0 + self.rise)
        else:
            near = self._start is not None and self._start < self.near
            progressed = self.best < self.progress * self.initial or near
            moved_away = progressed and d > self.best * (1.0 + self.rise)
        self.above = self.above + 1 if moved_away else 0
        return self.above >= self.patience, closer

    def should_stop(self, piece: np.ndarray, said: Stop | None, steps: int) -> Stop | None:
        if not self._watch:
            if said is not None:
                return said
            return Stop.LIMIT if steps >= self._limit else None
        if said is Stop.CAP:
            # past its cap, a controller runs on while every env step brings its piece closer than ever
            if self.overran >= self.overrun:
                return Stop.CAP
            self.overran += 1
            regressed, closer = self._regressed(piece)
            if regressed:
                return Stop.REGRESSED
            if not closer:
                return Stop.CAP
            return Stop.CAP if steps >= self._limit else None  # the skill's limit still bounds it
        if said is not None:
            return said
        if self._regressed(piece)[0]:
            return Stop.REGRESSED
        if steps >= self._limit:
            return Stop.CAP if self.overran else Stop.LIMIT  # an overrun cut short by the limit was at its cap
        return None

    def should_retry(self, pieces: int, expected: int, ended: Stop) -> bool:
        return ended is Stop.LIMIT or pieces < expected


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


def approach_pose(skill: Skill, piece: np.ndarray, goal: np.ndarray | None, *, scene: np.ndarray) -> ToolPose:
    """The skill's start pose for ``piece (P, 3)`` towards ``goal (G, 3)`` in ``scene (S, 3)``: ``scene=`` goes
    beyond the contract's two arguments, so a skill whose ``approach_pose`` takes only those is asked without
    it. A ``None`` goal reaches only skills that take one (heuristic controllers run with a sub-goal)."""
    try:
        return skill.approach_pose(piece, goal, scene=scene)  # type: ignore[call-arg,arg-type]
    except TypeError:  # a skill whose approach_pose has the two-argument contract signature
        return skill.approach_pose(piece, goal)  # type: ignore[arg-type]


#: GBTO's defaults for a skill without a scripted expert (demonstrations and task goals): Adam iterations and env
#: steps (the paper's demonstrations: 50 steps)
GBTO_ITERATIONS = 20
GBTO_STEPS = 50


def gbto_budget(skill: Skill | type[Skill]) -> tuple[int, int]:
    """``(iterations, steps)`` of trajectory optimisation for ``skill``: its plugin's ``training_defaults["demos"]``
    ``trajopt_iterations`` / ``trajopt_steps`` where it sets them, else :data:`GBTO_ITERATIONS` and
    :data:`GBTO_STEPS` (the paper's 50 steps). One budget for the skill's demonstrations, the ground-truth steps
    of tasks and single-skill evaluation, so its goals come from the same optimiser as its demonstrations."""
    own = dict((skill.training_defaults or {}).get("demos") or {})
    return int(own.get("trajopt_iterations", GBTO_ITERATIONS)), int(own.get("trajopt_steps", GBTO_STEPS))


class Replay(Controller):
    """Plays given actions ``(T, A)`` and stops with the last (what GBTO found)."""

    def __init__(self, actions: np.ndarray) -> None:
        self.actions = np.asarray(actions, np.float64)
        self.k = 0

    def reset(self, obs: SkillObservation) -> None:
        self.k = 0

    def act(self, obs: SkillObservation) -> tuple[np.ndarray, bool]:
        a = self.actions[min(self.k, len(self.actions) - 1)]
        self.k += 1
        return a, self.k >= len(self.actions)


def gbto_expert(sim: Any, skill: Skill, dough: np.ndarray, piece: np.ndarray, rng: np.random.Generator, *,
                iterations: int | None = None, steps: int | None = None, variant: str = "default"
                ) -> tuple[dict[str, Any], ToolPose, Replay]:
    """Gradient-based trajectory optimisation in place of a scripted expert, for a skill with ``demo_target``:
    the target of the piece ``dough[piece]`` (the rest of the observed ``dough (P, 3)`` stays where it is), the
    skill's approach pose for it, Adam on ``steps`` actions through the differentiable simulator
    (:func:`pasta.sim.trajopt.optimise_moves`, Traj-Opt's settings; ``iterations`` and ``steps``: default the skill's
    :func:`gbto_budget`). Returns the record (``expert: trajopt``,
    the losses, the best iteration), the approach pose and a controller replaying the best actions: run with
    :func:`run_skill` (``approach=``, ``max_steps=steps``) it makes the optimised rollout, the actions rounded
    to float32 as every controller's. ``sim`` is left as it was."""
    from pasta.config.run import TrajOptConfig
    from pasta.sim.trajopt import ToolMove, optimise_moves, tool_poses

    own_iterations, own_steps = gbto_budget(skill)
    iterations = own_iterations if iterations is None else int(iterations)
    steps = own_steps if steps is None else int(steps)
    piece = np.asarray(piece, np.int64)
    others = np.setdiff1d(np.arange(len(dough)), piece)
    moved = np.asarray(skill.demo_target(dough[piece], rng, variant), np.float32)
    approach = approach_pose(skill, dough[piece], moved, scene=dough)
    start = sim.get_state()
    sim.set_tool_pose(skill.tool, approach.position, yaw=approach.yaw)  # as run_skill places it
    move = ToolMove(skill.tool, tool_poses(sim))
    sim.set_state(start)
    base = TrajOptConfig()
    opt = optimise_moves(sim, [move], np.concatenate([dough[others], moved]), iterations=iterations, lr=base.lr,
                         steps=steps, points=base.points, blur=base.blur, contact=base.contact,
                         seed=int(rng.integers(2**31)), stage="gbto")
    record = {"expert": "trajopt", "losses": [round(v, 6) for v in opt.losses], "best_iteration": opt.best_iteration}
    return record, approach, Replay(opt.actions[0])


def run_skill(
    sim: Any,
    skill: Skill,
    controller: Controller,
    piece: Any,
    goal_points: np.ndarray | None,
    *,
    monitor: StepMonitor | None = None,
    max_steps: int | None = None,
    idle_steps: int = 10,
    approach: ToolPose | None = None,
    park: bool = True,
    record: bool = False,
) -> SkillRun:
    """Run one skill step in ``sim`` and return what happened.

    Args:
        sim: a :class:`pasta.sim.Simulator` with a scene loaded.
        skill: the skill (its ``tool`` is the one driven).
        controller: expert, heuristic controller or learned policy of that skill.
        piece: the attended piece, as a boolean mask ``(P,)`` or indices into the observed cloud.
        goal_points: ``(G, 3)`` sub-goal of the step (all produced pieces), or ``None`` (experts).
        monitor: decides when the step ends (:class:`pasta.core.StepMonitor`; default: a
            :class:`GoalMonitor` with its defaults). Whether the step should start at all is asked before
            (``monitor.should_run``), by whoever decides to run it.
        max_steps: the step limit in controller env steps (default: the skill's ``max_steps`` or 50).
        idle_steps: zero-action env steps after the controller stops (the dough settles).
        approach: start pose of the tool (default: the controller's ``approach_pose(piece, goal, scene=...)``
            when it has one and it returns a pose, e.g. a learned policy's reset pose, else
            ``skill.approach_pose(piece, goal, scene=...)``).
        park: teleport the tool to ``skill.park_pose()`` at the end.
        record: keep the observations and actions (:class:`Trajectory`).

    The loop: the controller sees the observation and returns ``(action, stop)``; a stop with an all-zero
    action ends the step without stepping; otherwise the action is applied and the monitor decides
    whether the step ends (the controller's stop, the step limit, or its own watch).
    """
    t0 = time.perf_counter()
    tool = skill.tool
    obs = sim.observe()
    idx = piece_indices(piece, len(obs.dough))
    limit = int(getattr(skill, "max_steps", 50)) if max_steps is None else int(max_steps)
    own_approach = getattr(controller, "approach_pose", None) if approach is None else None
    if callable(own_approach):
        # a controller with its own (learned) start pose; None falls back to the skill's
        approach = own_approach(obs.dough[idx], goal_points, scene=obs.dough)
    if approach is None:
        approach = approach_pose(skill, obs.dough[idx], goal_points, scene=obs.dough)
    sim.set_tool_pose(tool, approach.position, yaw=approach.yaw)
    obs = sim.observe()
    traj = Trajectory() if record else None
    view = skill_observation(obs, tool, idx, goal_points)
    controller.reset(view)
    monitor = monitor if monitor is not None else GoalMonitor()
    watch = bool(getattr(controller, "watch", False))
    said_unfinished = getattr(skill, "unfinished", None)  # Skill's hook; a bare test double may lack it
    goal_now = view.goal
    unfinished = None
    if callable(said_unfinished) and goal_now is not None and len(goal_now) > 0:
        def unfinished(piece: np.ndarray) -> bool:
            return bool(said_unfinished(piece, goal_now))
    monitor.begin(view.piece, view.goal, limit=limit, watch=watch, unfinished=unfinished)
    steps = 0
    ended: Stop | None = Stop.LIMIT if limit <= 0 else None
    path = [np.asarray(obs.tool_poses[tool][:3], np.float32)]
    while ended is None:
        action, said = controller.act(view)
        said = stop_reason(said)
        action = np.clip(np.asarray(action, np.float32).reshape(-1), -1.0, 1.0)
        if said is not None and not np.any(action):
            ended = said
            break
        if traj is not None:
            traj.add_obs(obs, tool)
            traj.action.append(action)
        sim.step({tool: action})
        steps += 1
        obs = sim.observe()
        path.append(np.asarray(obs.tool_poses[tool][:3], np.float32))
        view = skill_observation(obs, tool, idx, goal_points)
        ended = monitor.should_stop(view.piece, said, steps)
    if traj is not None:
        traj.add_obs(obs, tool)
    end_poses = {name: np.array(pose, np.float32) for name, pose in obs.tool_poses.items()}
    aperture = getattr(sim, "tool_aperture", None)
    end_apertures = {name: float(aperture(name)) for name in end_poses} if callable(aperture) else {}
    for _ in range(max(0, idle_steps)):
        sim.step()
    if park:
        pose = skill.park_pose()
        sim.set_tool_pose(tool, pose.position, yaw=pose.yaw)
    return SkillRun(skill.name, steps, ended, approach, time.perf_counter() - t0, traj, np.stack(path), end_poses,
                    end_apertures)
