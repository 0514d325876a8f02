"""pasta.planning.receding_search: the receding-horizon loop shared by receding_horizon and prefix_beam."""

from __future__ import annotations

import pytest
import torch

from pasta.planning import LatentPlannerConfig, receding_search
from pasta.testing import analytic_problem

CFG = LatentPlannerConfig(num_samples=16, iterations=20, clearance_weight=0.0)


def _run(sequences, window, seed=0):
    return receding_search(analytic_problem(horizon=3), sequences, CFG, torch.Generator().manual_seed(seed), window=window)


def test_commits_one_step_per_search_and_ends_on_a_given_sequence():
    sequences = [("split", "move", "flatten"), ("split", "flatten", "move")]
    res = _run(sequences, window=2)
    assert res.skeleton in sequences
    assert len(res.results) == len(res.attention) == len(res.subgoals) == 3
    assert [s["committed"] for s in res.stages()] == list(res.skeleton)
    assert res.stages()[0]["windows"] == 2  # ("split", "move") and ("split", "flatten")


def test_sequences_of_different_lengths_stop_where_the_best_window_ends():
    # sequences of 1, 2 and 3 steps, each a prefix of the next
    sequences = [("flatten",), ("flatten", "flatten"), ("flatten", "flatten", "flatten")]
    res = _run(sequences, window=1)
    assert res.skeleton in sequences
    # window 1: every search sees the one-step windows only, so the loop stops as soon as the committed
    # steps form a complete sequence
    assert res.skeleton == ("flatten",)


def test_same_seed_same_result():
    sequences = [("split", "move", "flatten"), ("split", "flatten", "move")]
    a, b = _run(sequences, 3, seed=5), _run(sequences, 3, seed=5)
    assert a.skeleton == b.skeleton and a.attention == b.attention
    assert all(torch.equal(x, y) for x, y in zip(a.subgoals, b.subgoals))


@pytest.mark.parametrize("window, sequences, match", [(0, [("split",)], "window"), (2, [], "at least one")])
def test_bad_arguments(window, sequences, match):
    with pytest.raises(ValueError, match=match):
        _run(sequences, window)
