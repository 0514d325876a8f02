"""``planner.draws=sequence``: a sequence's search does not depend on the other sequences searched with it."""

from __future__ import annotations

import pytest
import torch

from pasta.core import enumerate_skeletons
from pasta.core.errors import ConfigError
from pasta.planning import search
from pasta.planning.batch import sample_candidates, sequence_stream
from pasta.planning.config import HalvingConfig
from pasta.plugins import get_plugins
from pasta.testing import analytic_problem, configured

SMALL = {"num_samples": 16, "iterations": 20}


def _sequences(problem):
    return enumerate_skeletons([s.spec for s in problem.skills], problem.horizon, len(problem.obs), len(problem.goal))


def _scores(result):
    return {tuple(row["skills"]): row["score"] for row in result.per_sequence}


def test_sequence_draws_give_a_sequence_the_same_result_alone_and_among_others():
    problem = analytic_problem(horizon=3, seed=4)
    sequences = _sequences(problem)
    assert len(sequences) >= 3
    cfg = HalvingConfig(**SMALL, draws="sequence", refine_sequences=0)
    together = search(problem, sequences, cfg, torch.Generator().manual_seed(0))
    # another generator state and another company: the per-sequence streams ignore both
    alone = search(problem, [sequences[-1]], cfg, torch.Generator().manual_seed(99))
    pair = search(problem, [sequences[1], sequences[-1]], cfg, torch.Generator().manual_seed(5))
    want = _scores(together)[tuple(sequences[-1])]
    assert _scores(alone)[tuple(sequences[-1])] == pytest.approx(want, abs=1e-5)
    assert _scores(pair)[tuple(sequences[-1])] == pytest.approx(want, abs=1e-5)
    assert _scores(pair)[tuple(sequences[1])] == pytest.approx(_scores(together)[tuple(sequences[1])], abs=1e-5)


def test_shared_draws_depend_on_the_company_so_the_option_is_what_makes_them_equal():
    problem = analytic_problem(horizon=3, seed=4)
    sequences = _sequences(problem)
    cfg = HalvingConfig(**SMALL, draws="shared", refine_sequences=0)
    together = search(problem, sequences, cfg, torch.Generator().manual_seed(0))
    alone = search(problem, [sequences[-1]], cfg, torch.Generator().manual_seed(0))
    assert _scores(alone)[tuple(sequences[-1])] != _scores(together)[tuple(sequences[-1])]


def test_streams_differ_by_seed_and_sequence_and_repeat_for_the_same_pair():
    a = torch.rand(4, generator=sequence_stream(1, ("cut", "push")))
    assert torch.equal(a, torch.rand(4, generator=sequence_stream(1, ("cut", "push"))))
    assert not torch.equal(a, torch.rand(4, generator=sequence_stream(2, ("cut", "push"))))
    assert not torch.equal(a, torch.rand(4, generator=sequence_stream(1, ("push", "cut"))))
    # names are joined with a separator no skill name contains: ("ab", "c") is not ("a", "bc")
    assert not torch.equal(torch.rand(4, generator=sequence_stream(1, ("ab", "c"))),
                           torch.rand(4, generator=sequence_stream(1, ("a", "bc"))))


def test_candidates_of_a_sequence_do_not_depend_on_its_position():
    problem = analytic_problem(horizon=2)
    sequences = _sequences(problem)
    assert len(sequences) >= 2
    gen = torch.Generator().manual_seed(0)
    first = sample_candidates(problem.obs, problem.goal, sequences, problem.skill_map, problem.encoder, 8, gen,
                              sequence_seed=3)
    turned = sample_candidates(problem.obs, problem.goal, sequences[::-1], problem.skill_map, problem.encoder, 8, gen,
                               sequence_seed=3)

    def latents_of(batch, seq):
        index = batch.sequences.index(tuple(seq))
        return torch.cat([g.latents[g.seq == index] for g in batch.groups])

    for seq in sequences:
        assert torch.equal(latents_of(first, seq), latents_of(turned, seq))


@pytest.mark.parametrize("name", ["exhaustive", "prefix_beam"])
def test_planners_that_reach_the_same_sequence_score_it_the_same(name):
    """exhaustive and prefix_beam with draws=sequence: the beam's final score of the plan it picks is exactly
    exhaustive's score of that sequence (the final search is the same search, on fewer sequences)."""
    problem = analytic_problem(horizon=3, seed=2)
    over = {**SMALL, "draws": "sequence"}
    reference = configured(get_plugins().planners, "exhaustive", over).plan(problem)
    plan = configured(get_plugins().planners, name, over).plan(problem)
    rows = {tuple(r["skills"]): r["score"] for r in reference.info["per_sequence"]}
    assert rows[tuple(plan.skills)] == pytest.approx(plan.score, abs=1e-5)


def test_unknown_draw_mode_is_a_config_error():
    with pytest.raises(ConfigError, match="planner.draws"):
        HalvingConfig(draws="per_step")
