"""Which plan step runs next, on which observed pieces.

:func:`attend` maps a plan step's inputs to observed entities (the plan's input indices at a plan's first
step, then the observed entity nearest each planned centroid). :func:`next_step` runs the plan in its
order, except that a step whose push would sweep its piece (and its tool's band) through another observed
piece waits while a later step that does not depend on it runs first (:func:`sweep_risk`,
:func:`step_dependencies`); the plan's latent states do not change, only the order, and the executed
order is logged (``StepInfo.plan_step``).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from pasta.core.errors import InputError
from pasta.core.plan import Plan, PlanStep
from pasta.execute.goals import origins

__all__ = ["attend", "next_step", "step_dependencies", "sweep_risk"]


def step_dependencies(plan: Plan) -> list[set[int]]:
    """Per plan step, the earlier steps whose produced entities it consumes (directly)."""
    before = origins(plan)
    return [{before[h][i][0] for i in step.inputs if before[h][i][0] >= 0} for h, step in enumerate(plan.steps)]


def sweep_risk(piece: np.ndarray, target: np.ndarray, others: np.ndarray, *, half_width: float = 0.0,
               margin: float = 0.02) -> int:
    """Points of ``others (O, 3)`` in the band a push of ``piece (P, 3)`` to centroid ``target (2,)`` (x, z)
    sweeps: ahead of the piece's start, up to its front at the target, and within the piece's (or the
    tool's ``half_width``, whichever is wider) lateral half extent plus ``margin`` of the line."""
    if len(others) == 0 or len(piece) == 0:
        return 0
    xz = np.asarray(piece, np.float64)[:, [0, 2]]
    c = xz.mean(0)
    d = np.asarray(target, np.float64) - c
    length = float(np.linalg.norm(d))
    if length < 1e-3:
        return 0
    u = d / length
    n = np.array([-u[1], u[0]])
    rel = xz - c
    front = float((rel @ u).max())
    width = max(float(np.abs(rel @ n).max()), half_width) + margin
    q = np.asarray(others, np.float64)[:, [0, 2]] - c
    s, lat = q @ u, np.abs(q @ n)
    return int(np.count_nonzero((s > 0) & (s < length + front + margin) & (lat < width)))


def attend(labels: np.ndarray, points: np.ndarray, step: PlanStep, planned_before: Sequence[Sequence[float]],
           z_dim: int, first: bool) -> tuple[int, ...]:
    """Observed entity ids the step acts on.

    Args:
        labels: ``(P,)`` entity id of every observed point.
        points: ``(P, 3)`` observed dough.
        step: the plan step (its ``inputs`` index ``planned_before``).
        planned_before: ``(K, D)`` planned latent set before the step.
        z_dim: shape-code size ``Z``; the centroid is ``u[Z:Z+3]``.
        first: the first step of a plan: take the observed entities at the input indices when they exist.
    """
    k = int(labels.max()) + 1
    if first and all(i < k for i in step.inputs):
        return tuple(int(i) for i in step.inputs)
    centroids = np.stack([points[labels == e].mean(0) for e in range(k)])
    chosen: list[int] = []
    for i in step.inputs:
        t = np.asarray(planned_before[i], np.float64)[z_dim : z_dim + 3]
        d = np.linalg.norm(centroids - t, axis=1)
        d[chosen] = np.inf
        if not np.isfinite(d).any():
            raise InputError(f"step '{step.skill}' needs {len(step.inputs)} pieces but only {k} are observed")
        chosen.append(int(np.argmin(d)))
    return tuple(chosen)


def next_step(plan: Plan, executed: set[int], prepare: Callable[[int], tuple[Any, np.ndarray, list[np.ndarray]]],
              dough: np.ndarray, labels: np.ndarray, half_width: Callable[[str], float]) -> tuple[int, Any, np.ndarray,
                                                                                                  list[np.ndarray]]:
    """The plan step to run next: ``(index, attended, point indices (K,), goal pieces)``.

    Args:
        executed: plan steps already run.
        prepare: step index -> ``(attended entity ids, their point indices, the step's goal pieces)``.
        dough: ``(P, 3)`` the observed dough; ``labels``: ``(P,)`` its entity ids.
        half_width: skill name -> the half width its tool sweeps (:attr:`pasta.core.Skill.sweep_half_width`).
    """
    deps = step_dependencies(plan)
    ready = [j for j in range(len(plan.steps)) if j not in executed and deps[j] <= executed]
    first = None
    for j in ready:
        attended, idx, subgoal = prepare(j)
        if len(ready) == 1:
            return j, attended, idx, subgoal
        if first is None:
            first = (j, attended, idx, subgoal)
        others = dough[~np.isin(labels, attended)]
        target = np.concatenate(subgoal, 0)[:, [0, 2]].mean(0)
        if sweep_risk(dough[idx], target, others, half_width=half_width(plan.steps[j].skill)) == 0:
            return j, attended, idx, subgoal
    if first is None:
        raise InputError("no plan step is ready to run: every remaining step waits for another")
    return first
