"""The controller's goal for a plan step: decoded sub-goal latents, corrected by the observed goal.

A plan's sub-goals are latents; a controller needs point clouds. :func:`step_goal` decodes them and, in
the default ``execute.goal=observed`` mode, uses what is known exactly about the task's goal: a produced
entity that no later step touches is part of the plan's final state, which the planner matched to the
goal, so the controller gets that observed goal piece (decodings blur thin pieces: a rolled sheet decodes
about twice as thick); an output that only :attr:`~pasta.core.Skill.keeps_position` steps follow (a piece
pushed and then rolled) is aimed at its goal piece's place; and when every output of the step becomes
goal pieces through steps that keep mass (cut, push, roll), the outputs' point counts follow those goal
pieces' masses (the observation is a fixed particle subset, so counts are masses, and the cut controller
reads its split from them). ``execute.goal=decoded`` hands the controller the plain decodings, as the
paper does (docs/policies.md).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from pasta.core.errors import InputError
from pasta.core.plan import Plan, kept_indices
from pasta.core.skill import Skill

__all__ = ["anchor_xz", "equalise_density", "goal_descendants", "match_goal_pieces", "origins",
           "step_goal"]

def equalise_density(clouds: Sequence[np.ndarray], num_points: int, *, voxel: float = 1.0 / 64,
                     masses: Sequence[float] | None = None) -> list[np.ndarray]:
    """Resample ``clouds`` (each ``(N_i, 3)``) to point counts proportional to their volumes.

    The largest (by occupied ``voxel`` cells, or by ``masses`` when given: one per cloud, e.g. the point
    counts of the goal pieces they become) gets ``num_points`` points; points are taken in order (a
    decoder's Sobol template stays well spread) and repeated cyclically when a cloud has too few.
    """
    if len(clouds) < 2:
        return [np.asarray(c, np.float32) for c in clouds]
    if masses is not None:
        if len(masses) != len(clouds) or min(masses) <= 0:
            raise InputError(f"equalise_density: need one positive mass per cloud, got {list(masses)} for {len(clouds)} clouds")
        volumes = np.asarray(masses, np.float64)
    else:
        volumes = np.array([len(np.unique(np.floor(np.asarray(c) / voxel).astype(np.int64), axis=0)) for c in clouds],
                           np.float64)
    counts = np.maximum(1, np.round(num_points * volumes / volumes.max())).astype(int)
    return [np.asarray(c, np.float32)[np.arange(n) % len(c)] for c, n in zip(clouds, counts)]


def origins(plan: Plan) -> list[list[tuple[int, int]]]:
    """The set bookkeeping of ``plan``: for the set before each step and the final set, every entity as
    ``(step that produced it, output index)`` (``-1`` and its index for an initial entity)."""
    ids: list[tuple[int, int]] = [(-1, i) for i in range(len(plan.initial))]
    out = [ids]
    for k, step in enumerate(plan.steps):
        ids = [(k, j) for j in range(len(step.subgoal))] + [ids[i] for i in kept_indices(len(ids), step.inputs)]
        out.append(ids)
    return out


def goal_descendants(plan: Plan, h: int) -> dict[int, tuple[tuple[int, ...], tuple[str, ...]]]:
    """``{output j of step h: (indices in the final set it becomes, skills of the later steps on the way)}``.

    Follows what output ``j`` becomes through the later steps that consume it or its parts, as long as
    each of them takes a single entity (a cut splits it, a push or roll moves or shapes it; none adds
    another entity's dough). Empty skills: ``j`` itself persists. Outputs that a later many-entity step
    consumes (a merge) are left out.
    """
    before = origins(plan)
    final = {ent: pos for pos, ent in enumerate(before[-1])}
    out: dict[int, tuple[tuple[int, ...], tuple[str, ...]]] = {}
    for j in range(len(plan.steps[h].subgoal)):
        parts, chain = {(h, j)}, []
        for k in range(h + 1, len(plan.steps)):
            step = plan.steps[k]
            consumed = {before[k][i] for i in step.inputs} & parts
            if not consumed:
                continue
            if len(step.inputs) != 1:
                break
            parts = (parts - consumed) | {(k, m) for m in range(len(step.subgoal))}
            chain.append(step.skill)
        else:
            out[j] = (tuple(sorted(final[e] for e in parts)), tuple(chain))
    return out


def anchor_xz(cloud: np.ndarray, piece: np.ndarray) -> np.ndarray:
    """``cloud (N, 3)`` moved horizontally so that its x, z centroid is that of ``piece (M, 3)``."""
    cloud = np.asarray(cloud, np.float32).copy()
    shift = np.asarray(piece, np.float64)[:, [0, 2]].mean(0) - cloud[:, [0, 2]].astype(np.float64).mean(0)
    cloud[:, [0, 2]] += shift.astype(np.float32)
    return cloud


def match_goal_pieces(final: Sequence[Sequence[float]], goal: np.ndarray, labels: np.ndarray, z_dim: int) -> dict[int, np.ndarray]:
    """``{final-set index: goal piece (N, 3)}``: planned final entities matched to observed goal pieces by centroid."""
    from scipy.optimize import linear_sum_assignment

    k = int(labels.max()) + 1 if len(labels) else 0
    if k == 0 or len(final) == 0:
        return {}
    pieces = [goal[labels == e] for e in range(k)]
    planned = np.asarray(final, np.float64)[:, z_dim : z_dim + 3]
    dist = np.linalg.norm(planned[:, None, :] - np.stack([p.mean(0) for p in pieces])[None], axis=-1)
    rows, cols = linear_sum_assignment(dist)
    return {int(r): pieces[c] for r, c in zip(rows, cols)}


def step_goal(plan: Plan, j: int, encoder: Any, *, skills: Mapping[str, Skill], num_points: int,
              goal: np.ndarray | None = None, goal_labels: np.ndarray | None = None) -> list[np.ndarray]:
    """The controller's goal pieces for step ``j`` of ``plan``: one cloud ``(N_k, 3)`` per produced entity.

    Each sub-goal latent is decoded to ``num_points`` points. With the task's ``goal (G, 3)`` and its
    entity labels ``(G,)`` (``execute.goal=observed``), the corrections of the module docstring apply;
    without them (``decoded``), the decodings are resampled to point counts proportional to their decoded
    volumes (:func:`equalise_density`).
    """
    subgoal = encoder.decode_clouds(plan.steps[j].subgoal, num_points)
    masses: dict[int, float] = {}  # output -> point count of the goal piece it becomes
    if goal is not None and goal_labels is not None:
        matched = match_goal_pieces(plan.steps[-1].state, goal, goal_labels, encoder.z_dim)
        for k, (positions, chain) in goal_descendants(plan, j).items():
            if not all(pos in matched for pos in positions):
                continue
            masses[k] = float(sum(len(matched[pos]) for pos in positions))  # cuts, pushes and rolls keep mass
            if not chain:
                subgoal[k] = matched[positions[0]]
            elif len(positions) == 1 and all(getattr(skills[s], "keeps_position", False) for s in chain):
                subgoal[k] = anchor_xz(subgoal[k], matched[positions[0]])
    exact = len(masses) == len(subgoal)
    return equalise_density(subgoal, num_points, masses=[masses[k] for k in range(len(subgoal))] if exact else None)
