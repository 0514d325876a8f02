"""The grouped-by-skill batched evaluation agrees with a per-sample reference loop."""

from __future__ import annotations

import itertools

import torch

from pasta.core import CostModel, Skill, SkillSpec, kept_indices, min_cost_matching
from pasta.planning.batch import evaluate, sample_candidates
from pasta.testing import AnalyticEncoder


class _RandomSkill(Skill):
    """Feasibility from a small random permutation-invariant net (sum of per-entity features)."""

    def __init__(self, spec: SkillSpec, seed: int) -> None:
        self.spec_ = spec
        type(self).spec = spec
        super().__init__()
        g = torch.Generator().manual_seed(seed)
        self.w_in = torch.randn(5, 8, generator=g)
        self.w_out = torch.randn(5, 8, generator=g)
        self.head = torch.randn(8, generator=g)
        self.calls = 0

    def feasibility(self, u_in, u_out):
        self._check_tuple(u_in, u_out)
        self.calls += 1
        h = torch.tanh(u_in @ self.w_in).amax(1) + torch.tanh(u_out @ self.w_out).amax(1)
        return torch.sigmoid(h @ self.head)


def _skills():
    specs = [SkillSpec("cut", 1, 2, "knife"), SkillSpec("push", 1, 1, "pusher"), SkillSpec("merge", 2, 1, "gripper"), SkillSpec("roll", 1, 1, "roller")]
    # one class per skill: Skill.spec is a class attribute
    out = {}
    for i, s in enumerate(specs):
        cls = type(f"Skill_{s.name}", (_RandomSkill,), {})
        out[s.name] = cls(s, seed=i)
    return out


class _Cost(CostModel):
    def pairwise(self, a, b):
        return (a[:, :, None] - b[:, None]).pow(2).sum(-1).sqrt()


def _reference(start, goal, seq, attention, subgoals, skills, cost):
    """One sample: loop over steps with plain indexing; brute-force rectangular matching."""
    state, feas = start, []
    for name, inp, new in zip(seq, attention, subgoals):
        kept = kept_indices(len(state), inp)
        feas.append(float(skills[name].feasibility(state[list(inp)][None], new[None])[0]))
        state = torch.cat([new, state[list(kept)]])
    c = cost.pairwise(state[None], goal[None])[0]
    k, g = c.shape
    if k <= g:
        best = min(sum(float(c[i, j]) for i, j in enumerate(p)) for p in itertools.permutations(range(g), k))
    else:
        best = min(sum(float(c[i, j]) for j, i in enumerate(p)) for p in itertools.permutations(range(k), g))
    return feas, best


def test_grouped_evaluation_matches_per_sample_loop():
    skills, cost = _skills(), _Cost()
    gen = torch.Generator().manual_seed(3)
    start, goal = torch.rand(2, 5, generator=gen), torch.rand(3, 5, generator=gen)
    sequences = [("cut", "push", "roll"), ("cut", "roll", "push"), ("push", "cut", "roll"), ("roll", "push", "cut"), ("merge", "cut", "cut"),
                 ("cut", "merge", "cut"), ("push", "roll"), ("cut", "cut", "merge", "merge")]  # mixed lengths and end sizes
    batch = sample_candidates(start, goal, sequences, skills, AnalyticEncoder(), 7, gen)
    assert batch.size == 7 * len(sequences)
    assert len(batch.groups) < len(sequences)  # sequences sharing a cardinality signature share a group
    for s in skills.values():
        s.calls = 0
    for frozen_pass in (False, True):
        ev = evaluate(batch, batch.latents(), skills, cost)
        if frozen_pass:  # matched-pairs-only path with the matching just solved gives the same costs
            ev = evaluate(batch, batch.latents(), skills, cost, frozen=ev.matching)
        checked = 0
        for gi, grp in enumerate(batch.groups):
            for row in range(grp.size):
                seq, attention, subgoals = batch.candidate(gi, row)
                feas, c = _reference(start, goal, seq, attention, subgoals, skills, cost)
                torch.testing.assert_close(ev.feasibility[gi][row], torch.tensor(feas), rtol=1e-5, atol=1e-6)
                assert abs(float(ev.cost[gi][row]) - c) < 1e-5
                checked += 1
        assert checked == batch.size


def test_one_feasibility_call_per_skill():
    skills, cost = _skills(), _Cost()
    gen = torch.Generator().manual_seed(0)
    start, goal = torch.rand(1, 5, generator=gen), torch.rand(2, 5, generator=gen)
    sequences = [("cut", "push", "roll"), ("push", "cut", "roll"), ("roll", "roll", "cut"), ("cut", "roll", "push")]
    batch = sample_candidates(start, goal, sequences, skills, AnalyticEncoder(), 50, gen)
    for s in skills.values():
        s.calls = 0
    evaluate(batch, batch.latents(), skills, cost)
    assert {n: s.calls for n, s in skills.items()} == {"cut": 1, "push": 1, "roll": 1, "merge": 0}


def test_attention_is_uniform_and_sorted():
    skills = _skills()
    gen = torch.Generator().manual_seed(0)
    start, goal = torch.rand(3, 5, generator=gen), torch.rand(3, 5, generator=gen)
    batch = sample_candidates(start, goal, [("merge", "cut")], skills, AnalyticEncoder(), 3000, gen)
    inp = batch.groups[0].inputs[0]
    assert bool((inp[:, 0] < inp[:, 1]).all())
    counts = torch.bincount(inp[:, 0] * 3 + inp[:, 1], minlength=9)[[1, 2, 5]].double()
    assert bool(((counts / 3000 - 1 / 3).abs() < 0.04).all())
    kept = batch.groups[0].kept[0]
    assert bool((torch.sort(torch.cat([inp, kept], 1), 1).values == torch.arange(3)).all())


def test_min_cost_matching_used_for_square_sets():
    c = torch.rand(4, 2, 2)
    assert torch.allclose(min_cost_matching(c)[0], torch.minimum(c[:, 0, 0] + c[:, 1, 1], c[:, 0, 1] + c[:, 1, 0]))
