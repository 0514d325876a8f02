"""The oracle: the ground-truth skill chain executed by the heuristic controllers.

The oracle knows the skeleton, which piece each step acts on and the recorded intermediate goal
states, but NOT the experts' parameters: at step ``h`` the heuristic controller of the skill sees only
the observed attended piece and the sub-goal (the pieces the step produced in the recorded run). It
measures whether the tasks are solvable by point-cloud controllers and calibrates the thresholds.

The attended piece in the current (executed) scene is the DBSCAN cluster sharing the most observed
particles with the recorded input piece of the step (the ``n_in`` such clusters for a skill that consumes
several pieces; pieces are tracked by particle identity).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from pasta.core.decompose import decompose_labels
from pasta.tasks.base import Score, Task, TaskInstance
from pasta.tasks.step import SkillRun, run_skill

__all__ = ["OracleResult", "attended_piece", "run_oracle"]


@dataclass
class OracleResult:
    """One oracle episode: its score, the per-step runs and the wall time."""

    task: str
    seed: int
    score: Score
    runs: list[SkillRun] = field(default_factory=list)
    wall_s: float = 0.0


def attended_piece(dough: np.ndarray, recorded: np.ndarray, *, min_points: int = 10, n: int = 1) -> np.ndarray:
    """Indices of the ``n`` clusters of ``dough (P, 3)`` that share most points with ``recorded (K,)``
    (a skill consuming ``n`` pieces attends that many)."""
    labels = decompose_labels(dough, min_points=min_points)
    votes = np.bincount(labels[np.asarray(recorded, np.int64)], minlength=int(labels.max()) + 1)
    chosen = np.argsort(-votes, kind="stable")[:max(1, n)]
    return np.flatnonzero(np.isin(labels, chosen[votes[chosen] > 0]))


def run_oracle(task: Task, instance: TaskInstance, sim: Any = None) -> OracleResult:
    """Execute ``instance``'s ground-truth chain with heuristic controllers; score the final dough."""
    t0 = time.perf_counter()
    sim = sim if sim is not None else task.make_sim()
    sim.set_state(instance.init)
    runs = []
    for h, step in enumerate(instance.steps):
        skill = task.skill(step.skill)
        dough = sim.observe().dough
        piece = attended_piece(dough, step.inputs, n=skill.n_in)
        runs.append(run_skill(sim, skill, skill.controller(), piece, instance.step_goal(h),
                              idle_steps=task.config.idle_steps))
    score = task.score(sim.observe().dough, instance)
    return OracleResult(task.name, instance.seed, score, runs, time.perf_counter() - t0)
