"""Attention structures: which entities each step of a skill sequence consumes.

A step of skill ``k`` consumes ``N_k`` entities of the set before it; the next set is
``[produced (M_k), untouched...]`` (:mod:`pasta.core.plan`). Feasibility is permutation invariant, so a
step's attention is an unordered choice: a sorted tuple of ``N_k`` distinct indices.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

from pasta.core import PlanningProblem
from pasta.core.errors import InputError


def attention_structures(problem: PlanningProblem, skeleton: Sequence[str],
                         start_size: int | None = None) -> list[list[tuple[int, ...]]]:
    """Every attention structure of ``skeleton``: per step, a sorted tuple of the consumed entity indices.

    Args:
        problem: gives the skills' cardinalities (``problem.skill_map``) and, by default, the start set
            size ``K_0 = len(problem.obs)``.
        skeleton: ``H`` skill names.
        start_size: ``K_0`` when planning from another set (a receding-horizon window).

    Returns:
        ``prod_h C(K_h, N_h)`` structures, each a list of ``H`` tuples (step ``h``: ``N_h`` indices into
        the ``K_h`` entities before it), in lexicographic order. Small problems only: the count grows
        combinatorially (the built-in planners sample attention instead, see
        :func:`pasta.planning.batch.sample_candidates`).

    Raises:
        InputError: a step consumes more entities than the set holds, or a skill is not in the problem.
    """
    skills = problem.skill_map
    k = len(problem.obs) if start_size is None else int(start_size)
    for h, name in enumerate(skeleton):
        if name not in skills:
            raise InputError(f"skeleton step {h} uses skill '{name}', not one of the problem's skills {list(skills)}")
        spec = skills[name].spec
        if k < spec.n_in:
            raise InputError(f"skeleton {list(skeleton)} step {h}: '{name}' consumes {spec.n_in} entities of a set of {k}")
        k += spec.delta
    signature = [(skills[name].spec.n_in, skills[name].spec.n_out) for name in skeleton]
    return signature_structures(signature, len(problem.obs) if start_size is None else int(start_size))


def signature_structures(signature: Sequence[tuple[int, int]], start_size: int,
                         fixed_rows: Sequence[int] = ()) -> list[list[tuple[int, ...]]]:
    """Every attention structure of a cardinality ``signature`` ``((N_h, M_h), ...)`` from ``start_size``
    entities, in lexicographic order, never attending the entities at ``fixed_rows`` of the start set (after
    a step, such an entity sits at ``M_h`` + its rank among the kept ones, the set convention above)."""
    rows: list[tuple[list[tuple[int, ...]], list[int]]] = [([], list(fixed_rows))]
    k = int(start_size)
    for n, m in signature:
        grown = []
        for steps, fixed_now in rows:
            free = [i for i in range(k) if i not in fixed_now]
            for choice in itertools.combinations(free, n):
                kept = [i for i in range(k) if i not in choice]
                grown.append(([*steps, choice], [m + kept.index(p) for p in fixed_now]))
        rows, k = grown, k + m - n
    return [steps for steps, _ in rows]
