"""The closed loop: after each executed step, does the rest of the plan still fit what the camera sees?

:func:`plan_fit` is the test. The plan predicts the set of pieces before its next step: the pieces the steps
run so far produced, where those steps aimed them (the centroid of each output's goal piece as the controller
got it, :func:`pasta.execute.goals.step_goal`: the observed goal's place where the plan makes it exact, else
the decoded sub-goal), and the pieces they left alone, where the plan saw them. The observation gives the
pieces there are. The plan fits when the counts agree and, matching predicted to observed centroids one to one
(Hungarian, 3-D), no piece whose place the rest of the plan relies on is further than ``execute.fit_distance``
from where the plan expects it. The rest of the plan relies on a piece's place when no later step moves it
to a target of its own: it is final, or only steps that keep a piece's position (a roll:
:attr:`~pasta.core.Skill.keeps_position`) act on it and what they make (:func:`place_matters`). A piece that a
push will carry to its target anyway may lie anywhere (crs and cut_rearrange validation, no disturbance: the
cut's pieces land up to 8 cm from their decoded sub-goals, and are pushed to their goals all the same). A disturbance that splits, merges or adds
a piece changes the count; one that moves a piece moves its centroid; camera noise moves neither.

When the plan does not fit, the executor re-plans the remaining steps only, warm-started from the current plan
(:func:`pasta.execute.episode.replanner`): the remaining skill sequence first, and when that is not good enough
every sequence with one more skill inserted (:func:`warm_start_sequences`), so a disturbance that needs an extra
step (a merge needs a cut) can get it.

More pieces than any sequence of the registered skills can bring to the goal's count (a piece split in two, a
lump beside a piece, and no skill that joins two pieces: gather takes three) cannot be re-planned. Then each
observed piece that the plan cannot account for (left over when the plan's pieces are matched to the observed
ones) and made of dough the plan knew (not a lump dropped beside a piece) is joined to the observed piece whose
union with it lies where the plan expects that piece (:func:`extra_pieces`): from then on the two count as one entity,
by particle identity (:func:`join_labels`), so the step that acts on that piece acts on both: a push carries
the two to the piece's target together, where they merge.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from pasta.core.plan import Plan

__all__ = ["Fit", "extra_pieces", "join_labels", "place_matters", "plan_fit", "predicted_set", "remaining_skills",
           "warm_start_sequences"]


@dataclass(frozen=True)
class Fit:
    """The verdict of :func:`plan_fit`: ``fits``, why (one line), and the largest centroid distance (m; ``inf``
    when the counts differ, ``nan`` when the plan's order makes no prediction)."""

    fits: bool
    reason: str
    distance: float
    observed: int
    expected: int


def predicted_set(plan: Plan, executed: set[int], z_dim: int,
                  aimed: Mapping[tuple[int, int], np.ndarray] | None = None) -> np.ndarray | None:
    """``(K, 3)`` the centroids of the plan's set after the steps ``executed`` when they are a prefix of the
    plan (the usual case): output ``j`` of step ``k`` at ``aimed[(k, j)]`` where given, else at its latent's
    centroid; ``None`` after an out-of-order step (the plan then predicts no set)."""
    from pasta.execute.goals import origins

    k = len(executed)
    if executed != set(range(k)):
        return None
    state = plan.initial if k == 0 else plan.steps[k - 1].state
    latent = np.asarray([np.asarray(e, np.float64)[z_dim : z_dim + 3] for e in state])
    aimed = aimed or {}
    return np.stack([np.asarray(aimed[key], np.float64) if key in aimed else latent[i]
                     for i, key in enumerate(origins(plan)[k])])


def place_matters(plan: Plan, k: int, keeps_position: Callable[[str], bool]) -> list[bool]:
    """Per entity of the plan's set before step ``k``: does the rest of the plan rely on where it is? True when
    every later step that acts on it (or on what such a step made of it) keeps position and takes it alone."""
    from pasta.execute.goals import origins

    before = origins(plan)
    out = []
    for entity in before[k]:
        parts, matters = {entity}, True
        for j in range(k, plan.horizon):
            step = plan.steps[j]
            consumed = {before[j][i] for i in step.inputs} & parts
            if not consumed:
                continue
            if len(step.inputs) != 1 or not keeps_position(step.skill):
                matters = False
                break
            parts = (parts - consumed) | {(j, m) for m in range(len(step.subgoal))}
        out.append(matters)
    return out


def plan_fit(plan: Plan, executed: set[int], dough: np.ndarray, labels: np.ndarray, z_dim: int,
             distance: float, aimed: Mapping[tuple[int, int], np.ndarray] | None = None,
             keeps_position: Callable[[str], bool] = lambda name: False) -> Fit:
    """Does ``plan`` still fit the observed ``dough (P, 3)`` with entity ``labels (P,)`` after ``executed``?
    ``aimed``: ``(plan step, output) -> (3,)`` where the executor aimed that output; ``keeps_position``: skill
    name -> whether it keeps a piece's position (see the module docstring)."""
    from scipy.optimize import linear_sum_assignment

    observed = int(labels.max()) + 1 if len(labels) else 0
    planned = predicted_set(plan, executed, z_dim, aimed)
    if planned is None:
        return Fit(True, "steps ran out of plan order: no prediction to test, plan kept", float("nan"), observed, -1)
    expected = len(planned)
    if observed != expected:
        return Fit(False, f"{observed} pieces observed, the plan expects {expected}", float("inf"), observed, expected)
    centres = np.stack([dough[labels == e].mean(0) for e in range(observed)]).astype(np.float64)
    d = np.linalg.norm(planned[:, None] - centres[None], axis=-1)
    rows, cols = linear_sum_assignment(d)
    matters = np.asarray(place_matters(plan, len(executed), keeps_position))[rows]
    if not matters.any():
        return Fit(True, f"{observed} pieces, as the plan expects; later steps place every one of them", 0.0,
                   observed, expected)
    gaps = np.where(matters, d[rows, cols], -1.0)
    worst = float(gaps.max())
    if worst > distance:
        i = int(rows[np.argmax(gaps)])
        return Fit(False, f"piece {i} is {100 * worst:.1f} cm from where the plan expects it "
                          f"(execute.fit_distance {100 * distance:.1f} cm)", worst, observed, expected)
    return Fit(True, f"{observed} pieces; those that stay where they are lie within {100 * worst:.1f} cm of the "
                     f"plan (execute.fit_distance {100 * distance:.1f} cm)", worst, observed, expected)


def remaining_skills(plan: Plan, executed: set[int]) -> tuple[str, ...]:
    """The skills of ``plan``'s steps not yet ``executed``, in plan order: what a re-plan starts from."""
    return tuple(step.skill for j, step in enumerate(plan.steps) if j not in executed)


def warm_start_sequences(remaining: Sequence[str], skills: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    """The re-plan's candidate sequences: ``remaining`` itself first, then ``remaining`` with one skill of
    ``skills`` inserted at every position (the horizon grows by one), without repeats."""
    rest = tuple(remaining)
    out = [rest]
    for at in range(len(rest) + 1):
        for name in skills:
            out.append((*rest[:at], name, *rest[at:]))
    return tuple(dict.fromkeys(out))


def extra_pieces(plan: Plan, executed: set[int], dough: np.ndarray, labels: np.ndarray, z_dim: int,
                 aimed: Mapping[tuple[int, int], np.ndarray] | None = None, *, index: np.ndarray | None = None,
                 known: np.ndarray | None = None) -> list[tuple[int, int]]:
    """``[(extra, partner)]``: the observed pieces the plan cannot account for (more observed than predicted:
    those left over when predicted centroids are matched to observed ones), each with the matched observed
    piece it most likely belongs to: the one whose union with it lies closest (centroid, by point count) to
    where the plan expects that piece (the other half of a split piece). With the points' particle ids
    ``index (P,)`` and the ids ``known`` before the last step, an extra piece of mostly new dough (a lump
    dropped beside a piece) belongs to no piece of the plan and is left alone. Empty when the counts agree or
    the plan predicts no set."""
    from scipy.optimize import linear_sum_assignment

    planned = predicted_set(plan, executed, z_dim, aimed)
    k = int(labels.max()) + 1 if len(labels) else 0
    if planned is None or k <= len(planned):
        return []
    counts = np.bincount(labels, minlength=k).astype(np.float64)
    centres = np.stack([dough[labels == e].mean(0) for e in range(k)]).astype(np.float64)
    rows, cols = linear_sum_assignment(np.linalg.norm(planned[:, None] - centres[None], axis=-1))
    pairs = []
    for extra in sorted(set(range(k)) - set(cols.tolist())):
        if index is not None and known is not None and np.isin(index[labels == extra], known).mean() < 0.5:
            continue  # new dough, not a part of any piece the plan knows
        union = (counts[extra] * centres[extra] + counts[cols, None] * centres[cols]) / (counts[extra] + counts[cols])[:, None]
        miss = np.linalg.norm(union - planned[rows], axis=1)
        pairs.append((extra, int(cols[int(np.argmin(miss))])))
    return pairs


def join_labels(points: np.ndarray, labels: np.ndarray, index: np.ndarray, joined: Sequence[np.ndarray]) -> np.ndarray:
    """``labels (P,)`` of ``points (P, 3)`` with the pieces made of one group of ``joined`` (each an array of
    particle ids, matched against ``index (P,)``, the observed points' particle ids) made one; renumbered in
    :func:`pasta.core.decompose.decompose_labels`' order (centroid x, then z, then y).

    A piece is made of a group when at least half of its points are the group's particles: a stray particle
    that the perception counts with another piece (a noise point joins its nearest piece, and which piece is
    nearest changes when pieces move) does not drag that piece into the group."""
    labels = np.asarray(labels).copy()
    for group in joined:
        member = np.isin(index, group)
        inside = [e for e in np.unique(labels[member]) if member[labels == e].mean() >= 0.5]
        if len(inside) > 1:
            labels[np.isin(labels, inside)] = min(inside)
    kept = np.unique(labels)
    centroids = np.round(np.stack([points[labels == e].mean(0) for e in kept]), 6)
    order = np.lexsort((centroids[:, 1], centroids[:, 2], centroids[:, 0]))
    remap = np.empty(int(kept.max()) + 1, np.int64)
    remap[kept[order]] = np.arange(len(kept))
    return remap[labels]
