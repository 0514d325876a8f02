import itertools

import torch

from pasta.core import min_cost_matching
from pasta.nn.config import SetCostConfig
from pasta.nn.cost import PairCost, SetCostModel
from pasta.plugins import get_plugins


def brute_force(cost):
    b, k, g = cost.shape
    best = torch.full((b,), float("inf"))
    for perm in itertools.permutations(range(g), k):
        best = torch.minimum(best, cost[:, torch.arange(k), list(perm)].sum(-1))
    return best


def test_batched_matching_equals_brute_force():
    gen = torch.Generator().manual_seed(0)
    for k, g in [(1, 1), (1, 3), (2, 2), (2, 4), (3, 3), (3, 4), (4, 4), (3, 5), (5, 5), (4, 6)]:
        cost = torch.rand(64, k, g, generator=gen)
        total, assign = min_cost_matching(cost)
        assert torch.allclose(total, brute_force(cost), atol=1e-6), (k, g)
        assert (assign.sort(-1).values.unique_consecutive(dim=-1).shape[-1] == k)
        assert torch.allclose(cost.gather(2, assign[:, :, None]).squeeze(2).sum(-1), total)


def test_set_cost_is_matching_of_pair_network():
    torch.manual_seed(0)
    model = SetCostModel(SetCostConfig(weights=""), model=PairCost(5, hidden=16))
    a, b = torch.randn(8, 3, 5), torch.randn(8, 3, 5)
    with torch.no_grad():
        pair = model.pairwise(a, b)
        assert pair.shape == (8, 3, 3) and (pair >= 0).all()
        assert torch.allclose(model.set_cost(a, b), brute_force(pair), atol=1e-6)
        assert torch.allclose(model.set_cost(a, b), model.set_cost(a[:, [2, 0, 1]], b), atol=1e-6)
        assert torch.allclose(pair, model.pairwise(b, a).transpose(1, 2), atol=1e-6)  # symmetric
        shift = torch.tensor([0.0, 0.0, 0.2, 0.1, -0.3])
        assert torch.allclose(pair, model.pairwise(a + shift, b + shift), atol=1e-5)  # relative t only


def test_registered_and_needs_weights(tmp_path):
    import pytest

    from pasta.core.errors import MissingComponentError

    assert "set_cost" in get_plugins().cost_models.names()
    with pytest.raises(MissingComponentError, match="pasta train cost"):
        get_plugins().cost_models.create("set_cost", SetCostConfig(weights=str(tmp_path)))
