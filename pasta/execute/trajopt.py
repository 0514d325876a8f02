"""Traj-Opt, the paper's first baseline: gradient descent on a whole action sequence through the simulator.

The oracle setting of PASTA's table (as in DiffSkill's): the task's ground-truth tool chain is given (which tool
acts in which segment, e.g. knife, pusher, roller for crs), and each tool starts its segment at its skill's
approach pose for the recorded piece and sub-goal of that step (where an executed skill step places it). Every
action of every segment (``trajopt.steps`` env steps per tool, zeros at the start) is then optimised together by
Adam against the task's goal state (:func:`pasta.sim.trajopt.optimise_moves`: the Sinkhorn divergence with the
Euclidean cost between ``trajopt.points`` particles of the final state and the same particles of the goal, plus a
contact term). The sequence with the lowest loss is executed in the forward simulator (bitwise the optimised
rollout), the dough settles (``task.idle_steps``) and the task scores it.

What this baseline measures: how far gradients alone get through a long multi-tool horizon with no skill
abstraction. Costs and results: docs/simulator.md, "Traj-Opt".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pasta.sim.trajopt import ToolMove, execute_moves, optimise_moves, tool_poses

__all__ = ["Segment", "TrajOptResult", "chain_segments", "execute_chain", "run_trajopt"]


@dataclass
class Segment(ToolMove):
    """One step of the ground-truth chain as a tool move: its skill, its tool and every tool's pose when the
    segment starts (the active tool at its approach pose, the others where the executed chain leaves them:
    parked)."""

    skill: str = ""


@dataclass
class TrajOptResult:
    """One Traj-Opt episode: its score, the segments, the executed actions per segment ``(steps, channels)``,
    the loss of every iteration and the wall times of the optimisation and the final execution."""

    score: Any
    segments: list[Segment]
    actions: list[np.ndarray]
    losses: list[float] = field(default_factory=list)
    #: the task's normalised improvement of each iteration's rollout, before the dough settles (what the loss
    #: stands in for)
    improvements: list[float] = field(default_factory=list)
    best_iteration: int = -1
    optimise_s: float = 0.0
    execute_s: float = 0.0


def chain_segments(task: Any, instance: Any, sim: Any) -> list[Segment]:
    """The segments of ``instance``'s ground-truth chain, with each tool's pose at each segment's start as an
    executed chain has them: the tool of step ``h`` placed at its skill's approach pose for the recorded piece
    and sub-goal of the step (:func:`pasta.tasks.step.approach_pose`), the previous step's tool parked.
    ``sim`` is left in ``instance.init``."""
    from pasta.tasks.step import approach_pose

    sim.set_state(instance.init)
    start = {name: sim.tool_aperture(name) for name in sim.tool_names}
    segments = []
    before = instance.init_points
    previous = None
    for h, step in enumerate(instance.steps):
        skill = task.skill(step.skill)
        if previous is not None:
            park = previous.park_pose()
            sim.set_tool_pose(previous.tool, park.position, yaw=park.yaw, aperture=start[previous.tool])
        pose = approach_pose(skill, before[np.asarray(step.inputs, np.int64)], instance.step_goal(h), scene=before)
        sim.set_tool_pose(skill.tool, pose.position, yaw=pose.yaw, aperture=start[skill.tool])
        segments.append(Segment(skill.tool, tool_poses(sim), step.skill))
        before = np.asarray(step.state)[instance.obs_index]
        previous = skill
    sim.set_state(instance.init)
    return segments


def run_trajopt(task: Any, instance: Any, cfg: Any, *, sim: Any = None, seed: int = 0) -> TrajOptResult:
    """Optimise and execute ``instance``'s chain (module docstring); ``cfg``: ``trajopt.*``
    (:class:`pasta.config.run.TrajOptConfig`); ``seed`` draws the loss particles."""
    from pasta.core.errors import InputError

    sim = sim if sim is not None else task.make_sim()
    segments = chain_segments(task, instance, sim)
    if np.shape(instance.goal_state) != (sim.n_particles, 3):
        raise InputError(f"trajopt needs the goal of every simulated particle ({sim.n_particles}, 3), got "
                         f"{np.shape(instance.goal_state)}")

    def improvement(final: np.ndarray) -> float:
        return float(task.score(final[instance.obs_index], instance).improvement)

    opt = optimise_moves(sim, segments, instance.goal_state, iterations=int(cfg.iterations), lr=float(cfg.lr),
                         steps=int(cfg.steps), points=int(cfg.points), blur=float(cfg.blur), contact=float(cfg.contact),
                         seed=seed, watch=improvement)
    t1 = time.perf_counter()
    execute_chain(sim, instance, segments, opt.actions, idle_steps=int(task.config.idle_steps))
    score = task.score(sim.observe().dough, instance)
    return TrajOptResult(score, segments, opt.actions, opt.losses, opt.watched, opt.best_iteration, opt.seconds,
                         time.perf_counter() - t1)


def execute_chain(sim: Any, instance: Any, segments: list[Segment], actions: list[np.ndarray], *, idle_steps: int) -> None:
    """Run the chain in the forward simulator from ``instance.init``: each segment's poses, then its actions
    ``(steps, channels)``, then ``idle_steps`` zero-action steps at the end."""
    sim.set_state(instance.init)
    execute_moves(sim, segments, actions)
    for _ in range(max(0, idle_steps)):
        sim.step()
