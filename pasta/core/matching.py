"""Minimum-cost matching between two entity sets, batched.

For small sets (``max(K, G) <= 4``) every assignment is scored in one tensor operation; larger sets use
the Hungarian algorithm (scipy) per batch element.
"""

from __future__ import annotations

import itertools
from functools import lru_cache
from typing import TYPE_CHECKING, Any

from pasta.core.errors import InputError

if TYPE_CHECKING:
    import torch

#: Largest set size matched by enumerating assignments (4! = 24 permutations).
MAX_ENUMERATED = 4


def min_cost_matching(cost: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Match every row entity to a distinct column entity at minimum total cost.

    Args:
        cost: ``(B, K, G)`` pairwise costs with ``K <= G``.

    Returns:
        ``(total (B,), assignment (B, K))``: the minimum summed cost (differentiable with respect to
        ``cost``) and, for every row entity, the index of its column.
    """
    import torch

    if cost.ndim != 3:
        raise InputError(f"cost must have shape (B, K, G), got {tuple(cost.shape)}")
    b, k, g = cost.shape
    if k > g:
        raise InputError(f"cannot match {k} entities to only {g}: need K <= G")
    if k == 0:
        return cost.new_zeros(b), torch.zeros(b, 0, dtype=torch.long, device=cost.device)
    if g <= MAX_ENUMERATED:
        perms = torch.tensor(_assignments(k, g), dtype=torch.long, device=cost.device)  # (Q, K)
        rows = torch.arange(k, device=cost.device)
        totals = cost[:, rows, perms].sum(-1)  # (B, Q)
        best = totals.argmin(-1)
        return totals.gather(1, best[:, None]).squeeze(1), perms[best]
    from scipy.optimize import linear_sum_assignment

    import numpy as np

    host = cost.detach().cpu().numpy()
    cols = torch.from_numpy(np.stack([linear_sum_assignment(c)[1] for c in host])).to(cost.device)
    return cost.gather(2, cols[:, :, None]).squeeze(2).sum(-1), cols


@lru_cache(maxsize=64)
def _assignments(k: int, g: int) -> tuple[tuple[int, ...], ...]:
    return tuple(itertools.permutations(range(g), k))


#: Chamfer distance below which an observed entity counts as its goal entity, unchanged (the same
#: threshold labels "unchanged" entities in the feasibility training data, pasta.train.feasibility).
UNCHANGED_THRESHOLD = 5e-4


def unchanged_pairs(a: Any, b: Any, *, threshold: float = UNCHANGED_THRESHOLD, points: int = 200) -> list[tuple[int, int]]:
    """Pairs ``(i, j)`` of entities of ``a (Ka, P, 3)`` and ``b (Kb, Q, 3)`` that are the same piece, unchanged.

    Pairs are taken greedily, closest first, while their Chamfer distance (:func:`pasta.core.metrics.chamfer`,
    on the first ``points`` points of each cloud) is below ``threshold``; each entity is used at most once.
    ``threshold <= 0`` matches nothing. Returns the pairs sorted by ``i``.
    """
    import numpy as np

    from pasta.core.metrics import chamfer

    if threshold <= 0 or len(a) == 0 or len(b) == 0:
        return []
    a = np.asarray(a, np.float32)[:, :points]
    b = np.asarray(b, np.float32)[:, :points]
    d = np.asarray(chamfer(a[:, None], b[None]))  # (Ka, Kb)
    used_a, used_b, out = set(), set(), []
    for flat in np.argsort(d, axis=None, kind="stable"):
        i, j = (int(x) for x in np.unravel_index(flat, d.shape))
        if d[i, j] >= threshold:
            break
        if i not in used_a and j not in used_b:
            used_a.add(i)
            used_b.add(j)
            out.append((i, j))
    return sorted(out)
