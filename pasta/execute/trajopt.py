"""Traj-Opt, the paper's first baseline: gradient descent on a whole action sequence through the simulator.

The oracle setting of PASTA's table (as in DiffSkill's): the task's ground-truth tool chain is given (which tool
acts in which segment, e.g. knife, pusher, roller for crs), and each tool starts its segment at its skill's
approach pose for the recorded piece and sub-goal of that step (where an executed skill step places it). Every
action of every segment (``trajopt.steps`` env steps per tool, zeros at the start) is then optimised together by
Adam against the task's goal: the loss is the Sinkhorn divergence with the Euclidean cost (an EMD, as the tasks
score; :func:`pasta.sim.grad.sinkhorn` with ``p=1``, as the paper's geomloss loss) between ``trajopt.points``
particles of the final state and the same particles of the goal state, plus a small contact term that pulls a tool touching nothing toward the dough (without it, zero actions have a zero gradient). After
each step the actions are clipped to [-1, 1]; the sequence with the lowest loss is executed in the forward
simulator (bitwise the optimised rollout), the dough settles (``task.idle_steps``) and the task scores it.

What this baseline measures: how far gradients alone get through a long multi-tool horizon with no skill
abstraction. Costs and results: docs/simulator.md, "Traj-Opt".
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pasta.core import progress

__all__ = ["Segment", "TrajOptResult", "chain_segments", "execute_chain", "run_trajopt"]


@dataclass
class Segment:
    """One tool's part of the chain: its skill and tool, and every tool's pose ``(6,)`` (x, y, z, yaw, spin,
    aperture) when the segment starts (the active tool at its approach pose, the others where the executed
    chain leaves them: parked)."""

    skill: str
    tool: str
    poses: dict[str, np.ndarray]


@dataclass
class TrajOptResult:
    """One Traj-Opt episode: its score, the executed actions per segment ``(steps, channels)``, the loss of
    every iteration and the wall times of the optimisation and the final execution."""

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
        poses = {name: np.array([sim.tool_state(name)[c] for c in ("x", "y", "z", "yaw", "spin", "aperture")])
                 for name in sim.tool_names}
        segments.append(Segment(step.skill, skill.tool, poses))
        before = np.asarray(step.state)[instance.obs_index]
        previous = skill
    sim.set_state(instance.init)
    return segments


def run_trajopt(task: Any, instance: Any, cfg: Any, *, sim: Any = None, seed: int = 0) -> TrajOptResult:
    """Optimise and execute ``instance``'s chain (module docstring); ``cfg``: ``trajopt.*``
    (:class:`pasta.config.run.TrajOptConfig`); ``seed`` draws the loss particles."""
    import torch

    from pasta.sim.grad import chain_rows, rollout_rows, sinkhorn

    sim = sim if sim is not None else task.make_sim()
    segments = chain_segments(task, instance, sim)
    steps = int(cfg.steps)
    n = sim.n_particles
    goal_state = np.asarray(instance.goal_state, np.float32)
    if goal_state.shape != (n, 3):
        raise ValueError(f"trajopt needs the goal of every simulated particle ({n}, 3), got {goal_state.shape}")
    idx = np.sort(np.random.default_rng(seed).choice(n, size=min(int(cfg.points), n), replace=False))
    target = torch.as_tensor(goal_state[idx])
    actions = [torch.zeros(steps, sim.tool_spec(seg.tool).action_dim, dtype=torch.float64, requires_grad=True)
               for seg in segments]
    opt = torch.optim.Adam(actions, lr=float(cfg.lr))
    poses = [{k: torch.as_tensor(v, dtype=torch.float64) for k, v in seg.poses.items()} for seg in segments]
    losses: list[float] = []
    improvements: list[float] = []
    best, best_it = [a.detach().clone() for a in actions], -1
    t0 = time.perf_counter()
    for it in range(int(cfg.iterations)):
        opt.zero_grad()
        rows = chain_rows(sim, [({seg.tool: a}, p) for seg, a, p in zip(segments, actions, poses)])
        xs = rollout_rows(sim, rows, every_step=True)  # (T + 1, N, 3)
        shape = sinkhorn(xs[-1, idx].double(), target.double(), eps=float(cfg.blur), p=1)
        loss = shape + float(cfg.contact) * _contact(sim, rows, xs[:, idx], segments, steps)
        losses.append(float(shape.detach()))
        improvements.append(float(task.score(xs[-1].detach().numpy()[instance.obs_index], instance).improvement))
        if best_it < 0 or losses[-1] < losses[best_it]:
            best, best_it = [a.detach().clone() for a in actions], it
        progress.report("trajopt", it + 1, int(cfg.iterations), best_score=-losses[best_it], samples=it + 1)
        loss.backward()
        opt.step()
        with torch.no_grad():
            for a in actions:
                a.clamp_(-1.0, 1.0)
    optimise_s = time.perf_counter() - t0
    t1 = time.perf_counter()
    executed = [b.numpy() for b in best]
    execute_chain(sim, instance, segments, executed, idle_steps=int(task.config.idle_steps))
    score = task.score(sim.observe().dough, instance)
    return TrajOptResult(score, segments, executed, losses, improvements, best_it, optimise_s, time.perf_counter() - t1)


def execute_chain(sim: Any, instance: Any, segments: list[Segment], actions: list[np.ndarray], *, idle_steps: int) -> None:
    """Run the chain in the forward simulator from ``instance.init``: each segment's poses, then its actions
    ``(steps, channels)``, then ``idle_steps`` zero-action steps at the end."""
    sim.set_state(instance.init)
    for seg, acts in zip(segments, actions):
        for name, p in seg.poses.items():
            sim.set_tool_pose(name, p[:3], yaw=float(p[3]), aperture=float(p[5]))
        for a in acts:
            sim.step({seg.tool: a})
    for _ in range(max(0, idle_steps)):
        sim.step()


def _contact(sim: Any, rows: Any, xs: Any, segments: list[Segment], steps: int) -> Any:
    """Sum over every env step of the squared distance from the segment's active tool centre to the nearest of
    the loss particles ``xs (T + 1, P, 3)`` at the start of that step."""
    import torch

    from pasta.sim.grad import tool_positions

    total = torch.zeros((), dtype=torch.float64)
    for h, seg in enumerate(segments):
        lo, hi = h * steps, (h + 1) * steps
        centre = tool_positions(sim, rows[lo:hi], seg.tool)  # (steps, 3)
        d = torch.linalg.vector_norm(xs[lo:hi].double() - centre[:, None, :], dim=-1).min(dim=1).values
        total = total + (d ** 2).sum()
    return total
