"""Minimum-cost matching between two entity sets, batched.

For small sets (``max(K, G) <= 4``) every assignment is scored in one tensor operation; larger sets use
the Hungarian algorithm (scipy) per batch element.
"""

from __future__ import annotations

import itertools
from functools import lru_cache
from typing import TYPE_CHECKING

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
