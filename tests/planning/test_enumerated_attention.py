"""``attention="enumerate"``: every attention structure of a sequence, ``num_samples`` latent draws each
(the paper's "no sampling" ablation with one draw per structure)."""

from __future__ import annotations

from collections import Counter

import pytest
import torch

from pasta.config import ConfigError
from pasta.core import InputError
from pasta.planning import search, sample_candidates
from pasta.planning.attention import attention_structures
from pasta.planning.config import HalvingConfig
from pasta.testing import analytic_problem

from test_fixed_entities import crowded_problem  # the same crowded analytic problem


def _structures(batch):
    """Counter of (sequence, attention) over every candidate of ``batch``."""
    out = Counter()
    for gi, grp in enumerate(batch.groups):
        for row in range(grp.size):
            seq, att, _ = batch.candidate(gi, row)
            out[(seq, tuple(att))] += 1
    return out


@pytest.mark.parametrize("draws", [1, 3])
def test_every_structure_exactly_draws_times(draws):
    p = crowded_problem(2, match=False)  # three observed pieces: several structures per sequence
    seqs = p.skeletons()
    batch = sample_candidates(p.obs, p.goal, seqs, p.skill_map, p.encoder, draws, torch.Generator().manual_seed(0),
                              attention="enumerate")
    want = Counter({(tuple(s), tuple(a)): draws for s in seqs for a in attention_structures(p, s)})
    assert _structures(batch) == want
    assert batch.size == sum(want.values())


def test_enumeration_skips_fixed_entities_and_tracks_them():
    p = crowded_problem(3)  # pieces 1-3 sit at their goal
    seqs = p.skeletons()
    enum = sample_candidates(p.obs, p.goal, seqs, p.skill_map, p.encoder, 1, torch.Generator().manual_seed(0),
                             fixed=p.fixed, attention="enumerate")
    drawn = sample_candidates(p.obs, p.goal, seqs, p.skill_map, p.encoder, 400, torch.Generator().manual_seed(0),
                              fixed=p.fixed)
    got = _structures(enum)
    assert set(got) == set(_structures(drawn))  # the structures random draws reach, each once
    assert set(got.values()) == {1}
    for ge, gd in zip(enum.groups, drawn.groups):  # where the fixed entities end, as the sampler tracks it
        origin = torch.arange(len(p.obs)).expand(ge.size, -1)
        for (n, m), inp, kept in zip(ge.signature, ge.inputs, ge.kept):
            assert not bool((origin.gather(1, inp) >= 1).any())
            origin = torch.cat([torch.full((ge.size, m), -1), origin.gather(1, kept)], 1)
        assert torch.equal(origin.gather(1, ge.fixed_pos), torch.tensor([i for i, _ in p.fixed]).expand(ge.size, -1))


def test_unknown_attention_mode_is_refused():
    p = analytic_problem()
    with pytest.raises(InputError, match="attention"):
        sample_candidates(p.obs, p.goal, p.skeletons(), p.skill_map, p.encoder, 4, torch.Generator(), attention="all")
    with pytest.raises(ConfigError, match="planner.attention"):
        HalvingConfig(attention="enumarate")


def test_search_with_one_draw_per_structure_plans():
    p = analytic_problem(seed=0)
    seqs = p.skeletons()
    cfg = HalvingConfig(attention="enumerate", num_samples=1, refine_sequences=0, iterations=20)
    res = search(p, seqs, cfg, torch.Generator().manual_seed(0))
    assert res.samples == sum(len(attention_structures(p, s)) for s in seqs)
    assert res.skeleton in [tuple(s) for s in seqs] and res.score > 0
