"""Clearance: moving a piece through another costs, moving it away or past at a distance does not."""

from __future__ import annotations

import math

import torch

from pasta.core import PlanningProblem
from pasta.planning.batch import evaluate, sample_candidates
from pasta.planning.clearance import Clearance, half_extents, path_penalty
from pasta.planning.latent_rollout import build_plan, rollout
from pasta.testing import AnalyticCost, AnalyticEncoder, analytic_problem

HALF = torch.tensor([[[0.05, 0.05]]])  # (B=1, 1, 2) half extents


def _pen(start, end, obstacle, margin=0.0):
    return float(path_penalty(torch.tensor([start]), torch.tensor([[end]]), HALF, torch.tensor([[obstacle]]), HALF, margin)[0])


def test_path_through_an_obstacle_costs_and_a_clear_path_does_not():
    assert _pen([0.9, 0.5], [0.1, 0.5], [0.5, 0.5]) > 0.9  # straight through the middle: d_min = 0
    assert _pen([0.9, 0.5], [0.1, 0.5], [0.5, 0.8]) == 0.0  # passes 0.3 away, boxes 0.1 wide
    assert _pen([0.9, 0.5], [0.55, 0.5], [0.5, 0.5]) > 0.0  # ends on top of it


def test_moving_away_from_a_neighbour_is_free():
    # a cut's halves start touching (d_start < 1); separating them must not be penalised
    assert _pen([0.55, 0.5], [0.9, 0.5], [0.5, 0.5]) == 0.0
    # but moving closer to a neighbour already touching is
    assert _pen([0.58, 0.5], [0.52, 0.5], [0.5, 0.5]) > 0.0


def test_margin_widens_the_obstacle():
    assert _pen([0.9, 0.5], [0.1, 0.5], [0.5, 0.62]) == 0.0
    assert _pen([0.9, 0.5], [0.1, 0.5], [0.5, 0.62], margin=0.05) > 0.0


def test_gradient_moves_the_end_out_of_the_obstacle():
    end = torch.tensor([[[0.52, 0.5]]], requires_grad=True)
    p = path_penalty(torch.tensor([[0.9, 0.5]]), end, HALF, torch.tensor([[[0.5, 0.5]]]), HALF)
    p.sum().backward()
    assert end.grad[0, 0, 0] < 0  # descending the penalty moves the end to larger x, away from the obstacle


def test_half_extents_of_a_box():
    pts = torch.tensor([[[0.0, 0.0, 0.0], [0.2, 0.5, 0.1], [0.1, 0.2, 0.05]]])
    torch.testing.assert_close(half_extents(pts), torch.tensor([[0.1, 0.05]]))


def _two_piece_problem(horizon: int = 1) -> PlanningProblem:
    base = analytic_problem(horizon=horizon)
    enc = AnalyticEncoder()
    # two pieces on the floor plane (x, z) at 0.3 and 0.7; the goal swaps nothing, it only has two pieces
    obs = torch.tensor([[1.0, 0.0, 0.3, 0.05, 0.5], [1.0, 0.0, 0.7, 0.05, 0.5]])
    goal = torch.tensor([[1.0, 0.0, 0.2, 0.05, 0.5], [1.0, 0.0, 0.7, 0.05, 0.5]])
    return PlanningProblem(obs=obs, goal=goal, skills=base.skills, encoder=enc, cost=AnalyticCost(), horizon=horizon, seed=0)


def test_batched_penalty_matches_the_single_candidate_rollout():
    problem = _two_piece_problem(horizon=2)
    clearance = Clearance.from_problem(problem.encoder, problem.obs, problem.goal, margin=0.02)
    gen = torch.Generator().manual_seed(0)
    names = [s.name for s in problem.skills if s.n_in == 1 and s.n_out == 1]
    sequences = [(a, b) for a in names for b in names]
    batch = sample_candidates(problem.obs, problem.goal, sequences, problem.skill_map, problem.encoder, 16, gen)
    ev = evaluate(batch, batch.latents(), problem.skill_map, problem.cost, clearance=clearance)
    positive = 0
    for gi, grp in enumerate(batch.groups):
        for row in range(grp.size):
            seq, attention, subgoals = batch.candidate(gi, row)
            one = rollout(problem, seq, attention, [s.unsqueeze(0) for s in subgoals], clearance)
            assert abs(float(one.penalty[0]) - float(ev.penalty[gi][row])) < 1e-5
            positive += float(one.penalty[0]) > 0
    assert positive > 0  # random sub-goals do cross the other piece sometimes


def test_build_plan_counts_the_penalty_in_the_score():
    problem = _two_piece_problem(horizon=1)
    push = next(s.name for s in problem.skills if s.n_in == 1 and s.n_out == 1)
    # move the piece at x 0.3 onto the one at x 0.7: a collision
    subgoal = [torch.tensor([[1.0, 0.0, 0.7, 0.05, 0.5]])]
    plain = build_plan(problem, (push,), [(0,)], subgoal, planner="t", cost_weight=10.0, floor=0.01)
    checked = build_plan(problem, (push,), [(0,)], subgoal, planner="t", cost_weight=10.0, floor=0.01, clearance_weight=0.1)
    pen = checked.info["clearance_penalty"]
    assert pen > 0.5
    assert "clearance_penalty" not in plain.info
    assert math.isclose(checked.score, plain.score * math.exp(-10.0 * 0.1 * pen), rel_tol=1e-4)
    assert checked.final_cost == plain.final_cost  # the set cost is reported unchanged
