"""Entities already at their goal entity (``PlanningProblem.fixed``) are never attended and matched exactly."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from pasta.core import InputError, PlanningProblem
from pasta.core.matching import unchanged_pairs
from pasta.planning import rollout, sample_candidates
from pasta.plugins import get_plugins
from pasta.plugins.analytic import OPTIMAL_SKELETON, AnalyticCost, AnalyticEncoder, analytic_problem, analytic_skills
from pasta.plugins.checks import check_plan, configured

# pieces that sit at their goal already, away from the task's pieces (size, flatness, centroid)
EXTRA = [[0.5, 0.0, 0.45, 0.05, 0.15], [0.7, 0.3, 0.6, 0.05, 0.85], [0.3, 0.0, 0.8, 0.05, 0.15], [0.5, 0.5, 0.15, 0.05, 0.85]]


def crowded_problem(extra: int, *, seed: int = 0, match: bool = True) -> PlanningProblem:
    """The analytic problem with ``extra`` pieces added to both sets (the observed ones first: index 0 is the
    task's piece), ``fixed`` from the decoded clouds as the pipeline finds it (``match=False``: not given)."""
    base = analytic_problem(seed=seed)
    more = torch.tensor(EXTRA[:extra]).reshape(-1, 5)
    obs, goal = torch.cat([base.obs, more]), torch.cat([more.flip(0), base.goal])  # goal order differs
    enc = AnalyticEncoder()
    fixed = unchanged_pairs(enc.decode(obs, 256).numpy(), enc.decode(goal, 256).numpy()) if match else ()
    return PlanningProblem(obs, goal, analytic_skills(), enc, AnalyticCost(), horizon=3, seed=seed, fixed=tuple(fixed))


def attended_origins(plan, k0: int) -> set[int]:
    """Observed entities (indices into ``plan.initial``) that some step consumes."""
    origin: list = list(range(k0))
    out = set()
    for step in plan.steps:
        out |= {origin[i] for i in step.inputs if origin[i] is not None}
        kept = [origin[i] for i in range(len(origin)) if i not in step.inputs]
        origin = [None] * len(step.subgoal) + kept
    return out


def test_unchanged_pairs_matches_only_identical_pieces():
    enc = AnalyticEncoder()
    p = crowded_problem(3)
    pairs = unchanged_pairs(enc.decode(p.obs, 256).numpy(), enc.decode(p.goal, 256).numpy())
    assert pairs == [(1, 2), (2, 1), (3, 0)]  # the task's piece (0) matches no goal piece
    assert unchanged_pairs(enc.decode(p.obs, 256).numpy(), enc.decode(p.goal, 256).numpy(), threshold=0) == []


def test_problem_rejects_bad_fixed_pairs():
    p = crowded_problem(2)
    with pytest.raises(InputError, match="fixed"):
        PlanningProblem(p.obs, p.goal, p.skills, p.encoder, p.cost, horizon=3, fixed=((1, 0), (1, 1)))
    with pytest.raises(InputError, match="fixed"):
        PlanningProblem(p.obs, p.goal, p.skills, p.encoder, p.cost, horizon=3, fixed=((0, 9),))


def test_sampler_never_attends_fixed_entities_and_tracks_them():
    p = crowded_problem(4)
    gen = torch.Generator().manual_seed(0)
    batch = sample_candidates(p.obs, p.goal, p.skeletons(), p.skill_map, p.encoder, 64, gen, fixed=p.fixed)
    for grp in batch.groups:
        origin = torch.arange(len(p.obs)).expand(grp.size, -1)
        for (n, m), inp, kept in zip(grp.signature, grp.inputs, grp.kept):
            assert not bool((origin.gather(1, inp) >= 1).any())  # only the task's piece or new pieces
            origin = torch.cat([torch.full((grp.size, m), -1), origin.gather(1, kept)], 1)
        # fixed_pos says where each fixed entity ended
        assert torch.equal(origin.gather(1, grp.fixed_pos), torch.tensor([i for i, _ in p.fixed]).expand(grp.size, -1))


def test_no_fixed_entities_draw_what_they_drew_before():
    p = analytic_problem()
    a = sample_candidates(p.obs, p.goal, p.skeletons(), p.skill_map, p.encoder, 16, torch.Generator().manual_seed(3))
    b = sample_candidates(p.obs, p.goal, p.skeletons(), p.skill_map, p.encoder, 16, torch.Generator().manual_seed(3), fixed=())
    for ga, gb in zip(a.groups, b.groups):
        assert all(torch.equal(x, y) for x, y in zip(ga.inputs, gb.inputs)) and torch.equal(ga.latents, gb.latents)


@pytest.mark.parametrize("name", ["exhaustive", "sampling", "receding_horizon"])
def test_pieces_at_their_goal_are_never_attended(name):
    planner = configured(get_plugins().planners, name, {"iterations": 60, "num_samples": 64})
    p = crowded_problem(4, seed=1)
    assert len(p.fixed) == 4
    plan = planner.plan(p)
    check_plan(plan, p, cost_weight=planner.config.cost_weight)  # score and cost as rollout computes them
    if name != "sampling":  # CEM needs ~4x the samples to solve the analytic problem (docs/planning.md)
        assert plan.skills == OPTIMAL_SKELETON
    assert attended_origins(plan, len(p.obs)) == {0}
    assert plan.info["fixed"] == [list(x) for x in p.fixed]
    assert plan.to_json(timings=False) == planner.plan(crowded_problem(4, seed=1)).to_json(timings=False)


def test_fixed_pairs_are_matched_to_their_goal_entities_in_the_set_cost():
    # the set cost must pair a fixed entity with the goal entity it is fixed to, even where the free
    # matching would pair it otherwise: fix each extra piece to the *other* extra piece's goal entity
    p = crowded_problem(2)  # obs: task piece, extra 0, extra 1; goal: extra 1, extra 0, the task's two pieces
    assert p.fixed == ((1, 1), (2, 0))
    free = PlanningProblem(p.obs, p.goal, p.skills, p.encoder, p.cost, horizon=1)
    swapped = PlanningProblem(p.obs, p.goal, p.skills, p.encoder, p.cost, horizon=1, fixed=((1, 0), (2, 1)))
    sub = [p.goal[None, 2:4]]  # split the task piece into exactly its two goal pieces
    c_free = float(rollout(free, ("split",), [(0,)], sub).cost)
    c_right = float(rollout(p, ("split",), [(0,)], sub).cost)
    c_swapped = float(rollout(swapped, ("split",), [(0,)], sub).cost)
    assert c_free == pytest.approx(0.0, abs=1e-9) and c_right == pytest.approx(0.0, abs=1e-9)
    pair = float(p.cost.pairwise(p.obs[None, 1:2], p.obs[None, 2:3]))  # extra 0 against extra 1
    assert c_swapped == pytest.approx(2 * pair, rel=1e-5) and pair > 0.1


def box(centre, size, n, rng):
    return (np.asarray(centre) + (rng.random((n, 3)) - 0.5) * np.asarray(size)).astype(np.float32)


def test_pipeline_keeps_pieces_at_their_goal_out_of_a_real_plan():
    """Shipped networks, clouds as `pasta run` sees them: a crs-like dough and goal plus 3 cubes that sit at
    their goal pieces; the plan attends none of the cubes (they are found and kept out), and with the
    matching off (`unchanged_threshold=0`) nothing is kept out."""
    import dataclasses

    from pasta.execute.episode import perceive_and_plan
    from pasta.execute.session import build_session

    s = build_session("crs", ["planner.num_samples=16", "planner.iterations=20"])
    rng = np.random.default_rng(0)
    cubes = [box(c, (0.06, 0.06, 0.06), 150, rng) for c in ((0.3, 0.04, 0.13), (0.55, 0.04, 0.87), (0.75, 0.04, 0.13))]
    obs = np.concatenate([box((0.775, 0.05, 0.5), (0.25, 0.08, 0.07), 700, rng), *cubes])
    goal = np.concatenate([box((0.825, 0.05, 0.5), (0.15, 0.08, 0.07), 420, rng),
                           box((0.27, 0.02, 0.5), (0.25, 0.018, 0.12), 280, rng), *cubes])
    plan = perceive_and_plan(obs, goal, planner=s.planner, skills=s.skills, encoder=s.encoder, cost=s.cost, horizon=3,
                             seed=0, perception=s.perception).plan
    cube_ids = {i for i, _ in plan.info["fixed"]}
    assert len(cube_ids) == 3  # every cube found at its goal piece, the dough not
    assert not attended_origins(plan, len(plan.initial)) & cube_ids
    off = perceive_and_plan(obs, goal, planner=s.planner, skills=s.skills, encoder=s.encoder, cost=s.cost, horizon=3,
                            seed=0, perception=dataclasses.replace(s.perception, unchanged_threshold=0.0)).plan
    assert "fixed" not in off.info


def test_the_beams_local_search_never_attends_pieces_at_their_goal():
    """planner.polish searches sequences the beam never built; those must keep the fixed entities out too."""
    planner = configured(get_plugins().planners, "prefix_beam",
                         {"iterations": 60, "num_samples": 64, "prefix_samples": 16, "prefix_iterations": 20,
                          "final": 1, "polish": 3, "max_horizon": 3})
    p = crowded_problem(4, seed=1)
    plan = planner.plan(p)
    assert plan.info["polish"]  # the local search ran
    check_plan(plan, p, cost_weight=planner.config.cost_weight)
    assert attended_origins(plan, len(p.obs)) == {0}
    assert plan.info["fixed"] == [list(x) for x in p.fixed]
