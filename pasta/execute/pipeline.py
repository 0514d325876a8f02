"""One task episode end to end: perception -> plan -> execution -> score (what ``pasta run`` does).

- :func:`perceive`: decompose a dough cloud (DBSCAN, ``min_points`` 50) and encode every entity.
- :func:`plan_from_clouds`: perceive the observation and the goal, build the planning problem, plan.
- :func:`run_episode`: plan and execute in a simulator, optionally re-planning after every step.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from pasta.core.decompose import decompose
from pasta.core.plan import Plan
from pasta.execute.executor import ExecuteConfig, ExecutionResult, execute_plan

__all__ = ["Episode", "perceive", "plan_from_clouds", "run_episode"]


def perceive(points: np.ndarray, encoder: Any, *, min_points: int = 50, num_points: int = 1000,
             seed: int = 0) -> tuple[list[np.ndarray], Any]:
    """Entities of ``points (P, 3)`` (each ``(num_points, 3)``) and their latents ``(K, D)`` (torch).

    An encoder of ``scope == "scene"`` (the Flat 3D baseline) gets the whole cloud as one entity.
    """
    import torch

    if getattr(encoder, "scope", "entity") == "scene":  # Flat 3D: the whole cloud is the one entity
        pts = np.asarray(points, np.float32)
        rng = np.random.default_rng(seed)
        entities = [pts[rng.choice(len(pts), num_points, replace=len(pts) < num_points)]]
    else:
        entities = decompose(points, min_points=min_points, num_points=num_points, seed=seed)
    with torch.no_grad():
        latents = encoder.encode(torch.as_tensor(np.stack(entities)))
    return entities, latents.detach().cpu().float()


def plan_from_clouds(obs: np.ndarray, goal: np.ndarray, *, planner: Any, skills: Sequence[Any], encoder: Any,
                     cost: Any, horizon: int, seed: int = 0, skeleton: Sequence[str] | None = None,
                     min_points: int = 50, num_points: int = 1000, unchanged_threshold: float = 5e-4) -> Plan:
    """Perceive ``obs (P, 3)`` and ``goal (G, 3)`` and plan ``horizon`` steps with ``planner``.

    Observed entities within ``unchanged_threshold`` (Chamfer) of a goal entity are that goal piece
    already (``PlanningProblem.fixed``: never attended, matched to it; 0 disables).
    """
    from pasta.core.matching import unchanged_pairs
    from pasta.core.planner import PlanningProblem

    e_obs, u_obs = perceive(obs, encoder, min_points=min_points, num_points=num_points, seed=seed)
    e_goal, u_goal = perceive(goal, encoder, min_points=min_points, num_points=num_points, seed=seed)
    scene = getattr(encoder, "scope", "entity") == "scene"  # Flat 3D: one entity, nothing to keep apart
    fixed = () if scene else unchanged_pairs(np.stack(e_obs), np.stack(e_goal), threshold=unchanged_threshold)
    problem = PlanningProblem(obs=u_obs, goal=u_goal, skills=list(skills), encoder=encoder, cost=cost,
                              horizon=horizon, seed=seed, skeleton=tuple(skeleton) if skeleton else None,
                              fixed=tuple(fixed))
    return planner.plan(problem)


@dataclass
class Episode:
    """A planned and executed episode: the first plan and the execution result."""

    plan: Plan
    result: ExecutionResult


def run_episode(sim: Any, goal: np.ndarray, *, planner: Any, skills: Sequence[Any], encoder: Any, cost: Any,
                horizon: int, seed: int = 0, skeleton: Sequence[str] | None = None,
                cfg: ExecuteConfig | None = None, logger: Any = None) -> Episode:
    """Plan from ``sim``'s current observation to ``goal (G, 3)`` and execute (see :func:`execute_plan`)."""
    cfg = cfg or ExecuteConfig()
    kw = dict(planner=planner, skills=skills, encoder=encoder, cost=cost, seed=seed, min_points=cfg.min_points,
              unchanged_threshold=cfg.unchanged_threshold)
    plan = plan_from_clouds(sim.observe().dough, goal, horizon=horizon, skeleton=skeleton, **kw)

    def replan(dough: np.ndarray, steps_left: int) -> Plan:
        done = horizon - steps_left
        rest = tuple(skeleton[done:]) if skeleton else None
        return plan_from_clouds(dough, goal, horizon=steps_left, skeleton=rest, **kw)

    result = execute_plan(sim, plan, skills={s.name: s for s in skills}, encoder=encoder, goal=goal, cfg=cfg,
                          replan=replan if cfg.closed_loop else None, logger=logger)
    return Episode(plan, result)
