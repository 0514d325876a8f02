import itertools

import pytest
import torch

from pasta.core import InputError, min_cost_matching


def brute_force(cost: torch.Tensor) -> torch.Tensor:
    b, k, g = cost.shape
    best = torch.full((b,), float("inf"))
    for perm in itertools.permutations(range(g), k):
        best = torch.minimum(best, cost[:, torch.arange(k), list(perm)].sum(-1))
    return best


@pytest.mark.parametrize("k, g", [(1, 1), (2, 2), (3, 3), (2, 4), (4, 4), (5, 5), (3, 6)])
def test_batched_matching_equals_brute_force(k, g):
    cost = torch.rand(64, k, g, generator=torch.Generator().manual_seed(k * 10 + g))
    total, assignment = min_cost_matching(cost)
    assert torch.allclose(total, brute_force(cost), atol=1e-6)
    assert assignment.shape == (64, k)
    assert all(len(set(row.tolist())) == k for row in assignment)
    assert torch.allclose(cost.gather(2, assignment[:, :, None]).squeeze(2).sum(-1), total)


def test_matching_is_differentiable_on_the_enumerated_path():
    cost = torch.rand(8, 3, 3, requires_grad=True)
    min_cost_matching(cost)[0].sum().backward()
    assert torch.allclose(cost.grad.sum((1, 2)), torch.full((8,), 3.0))


def test_more_rows_than_columns_is_an_error():
    with pytest.raises(InputError, match="cannot match 3 entities to only 2"):
        min_cost_matching(torch.zeros(1, 3, 2))
