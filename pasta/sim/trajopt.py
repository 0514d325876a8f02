"""Gradient descent on tool moves through the differentiable simulator: what Traj-Opt (``method=trajopt``,
:mod:`pasta.execute.trajopt`) and GBTO demonstrations (``pasta demos expert=trajopt``, :mod:`pasta.demos.generate`)
both run.

A chain is a list of :class:`ToolMove`: one tool acting for ``steps`` env steps from given poses of every tool
(a skill step places its tool; the next one parks it). :func:`optimise_moves` runs Adam on all the chain's actions
together, from zeros, against a target cloud: the loss is the Sinkhorn divergence with the Euclidean cost
(:func:`pasta.sim.grad.sinkhorn` with ``p=1``, the paper's geomloss loss, an EMD as the tasks score) between
``points`` particles of the final state and ``points`` points of the target, plus a contact term, the squared
distance from each step's active tool centre to the nearest of those particles, which pulls a tool that touches
nothing toward the dough (zero actions otherwise have a zero gradient). After each Adam step the actions are
clipped to [-1, 1]; the actions with the lowest loss seen are returned. :func:`execute_moves` runs them in the
forward simulator, which computes bitwise the optimised rollout.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["GRADIENT_STEPS", "Optimised", "ToolMove", "execute_moves", "optimise_moves", "tool_poses"]

#: what one env step of an optimiser iteration (rollout and backward) costs, in forward simulator steps
#: (benchmarks/bench_grad.py: 5.6-8x); the deadlines of `pasta eval method=trajopt` and GBTO demos use it
GRADIENT_STEPS = 8


@dataclass
class ToolMove:
    """One tool acting: ``tool`` and every simulated tool's pose ``(6,)`` (x, y, z, yaw, spin, aperture) when the
    move starts."""

    tool: str
    poses: dict[str, np.ndarray]


@dataclass
class Optimised:
    """The best actions per move ``(steps, channels)``, the loss of every iteration, what ``watch`` said of each
    iteration's final particles, the best iteration and the wall time."""

    actions: list[np.ndarray]
    losses: list[float] = field(default_factory=list)
    watched: list[float] = field(default_factory=list)
    best_iteration: int = -1
    seconds: float = 0.0


def tool_poses(sim: Any) -> dict[str, np.ndarray]:
    """Every simulated tool's pose row ``(6,)`` now (what a :class:`ToolMove` starts from)."""
    cols = ("x", "y", "z", "yaw", "spin", "aperture")
    return {name: np.array([sim.tool_state(name)[c] for c in cols]) for name in sim.tool_names}


def optimise_moves(sim: Any, moves: Sequence[ToolMove], target: np.ndarray, *, iterations: int, lr: float, steps: int,
                   points: int, blur: float, contact: float, seed: int = 0,
                   watch: Callable[[np.ndarray], float] | None = None, stage: str = "trajopt") -> Optimised:
    """Adam on the actions of ``moves`` (``steps`` each) from ``sim``'s current state toward ``target (G, 3)``
    (module docstring). ``seed`` draws the loss particles (and the target's points when ``target`` is not every
    particle's goal, ``G != N``; when it is, the same particles are compared, as the paper's solver does);
    ``watch(final particles (N, 3))`` is recorded per iteration; progress is reported as ``stage``."""
    import torch

    from pasta.core import progress
    from pasta.core.errors import InputError
    from pasta.sim.grad import chain_rows, rollout_rows, sinkhorn

    target = np.asarray(target, np.float32)
    if target.ndim != 2 or target.shape[1] != 3 or len(target) < 1 or not np.isfinite(target).all():
        raise InputError(f"the target must be a finite (G, 3) cloud, got shape {target.shape}")
    n = sim.n_particles
    rng = np.random.default_rng(seed)
    idx = np.sort(rng.choice(n, size=min(int(points), n), replace=False))
    tidx = idx if len(target) == n else np.sort(rng.choice(len(target), size=min(int(points), len(target)),
                                                           replace=False))
    goal = torch.as_tensor(target[tidx])
    actions = [torch.zeros(steps, sim.tool_spec(m.tool).action_dim, dtype=torch.float64, requires_grad=True)
               for m in moves]
    opt = torch.optim.Adam(actions, lr=float(lr))
    poses = [{k: torch.as_tensor(v, dtype=torch.float64) for k, v in m.poses.items()} for m in moves]
    out = Optimised([a.detach().clone().numpy() for a in actions])
    t0 = time.perf_counter()
    for it in range(int(iterations)):
        opt.zero_grad()
        rows = chain_rows(sim, [({m.tool: a}, p) for m, a, p in zip(moves, actions, poses)])
        xs = rollout_rows(sim, rows, every_step=True)  # (T + 1, N, 3)
        shape = sinkhorn(xs[-1, idx].double(), goal.double(), eps=float(blur), p=1)
        loss = shape + float(contact) * _contact(sim, rows, xs[:, idx], moves, steps)
        out.losses.append(float(shape.detach()))
        if watch is not None:
            out.watched.append(float(watch(xs[-1].detach().numpy())))
        if out.best_iteration < 0 or out.losses[-1] < out.losses[out.best_iteration]:
            out.actions, out.best_iteration = [a.detach().clone().numpy() for a in actions], it
        progress.report(stage, it + 1, int(iterations), best_score=-out.losses[out.best_iteration], samples=it + 1)
        loss.backward()
        opt.step()
        with torch.no_grad():
            for a in actions:
                a.clamp_(-1.0, 1.0)
    out.seconds = time.perf_counter() - t0
    return out


def execute_moves(sim: Any, moves: Sequence[ToolMove], actions: Sequence[np.ndarray]) -> None:
    """Run the moves in the forward simulator from its current state: each move's poses, then its actions."""
    for move, acts in zip(moves, actions):
        for name, p in move.poses.items():
            sim.set_tool_pose(name, p[:3], yaw=float(p[3]), aperture=float(p[5]))
        for a in acts:
            sim.step({move.tool: a})


def _contact(sim: Any, rows: Any, xs: Any, moves: Sequence[ToolMove], steps: int) -> Any:
    """Sum over every env step of the squared distance from the move's active tool centre to the nearest of the
    loss particles ``xs (T + 1, P, 3)`` at the start of that step."""
    import torch

    from pasta.sim.grad import tool_positions

    total = torch.zeros((), dtype=torch.float64)
    for h, move in enumerate(moves):
        lo, hi = h * steps, (h + 1) * steps
        centre = tool_positions(sim, rows[lo:hi], move.tool)  # (steps, 3)
        d = torch.linalg.vector_norm(xs[lo:hi].double() - centre[:, None, :], dim=-1).min(dim=1).values
        total = total + (d ** 2).sum()
    return total
