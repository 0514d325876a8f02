"""Planner behaviour beyond the contract: determinism, gradient vs sampling, horizons, windows, errors."""

from __future__ import annotations

import dataclasses

import pytest
import torch

from pasta.config import load_config, section
from pasta.core import CardinalityError, Plan
from pasta.plugins import get_plugins
from pasta.testing import OPTIMAL_SKELETON, analytic_problem, check_plan, configured

PLANNERS = ["exhaustive", "sampling", "receding_horizon"]


def make(name: str, **overrides):
    return configured(get_plugins().planners, name, {"iterations": 60, "num_samples": 64, **overrides})


@pytest.mark.parametrize("name", PLANNERS)
def test_same_seed_same_bytes_and_plan_fields(name):
    planner = make(name, num_samples=32, iterations=20)
    a, b = planner.plan(analytic_problem(seed=5)), planner.plan(analytic_problem(seed=5))
    assert a.to_json(timings=False) == b.to_json(timings=False)
    assert Plan.from_json(a.to_json()).to_json() == a.to_json()
    assert {"enumerate", "sample", "optimise", "select", "total"} <= set(a.timings)
    assert a.info["samples"] > 0 and a.info["sequences"] >= 1 and a.info["evaluations"] >= a.info["samples"]
    assert a.planner == name and a.seed == 5


def test_different_seeds_give_different_candidates():
    planner = make("exhaustive", num_samples=16, iterations=5)
    a, b = planner.plan(analytic_problem(seed=0)), planner.plan(analytic_problem(seed=1))
    assert a.to_json(timings=False) != b.to_json(timings=False)


@pytest.mark.parametrize("name", PLANNERS)
def test_impossible_cardinality_raises(name):
    problem = analytic_problem(horizon=1, goal=torch.full((3, 5), 0.5))
    with pytest.raises(CardinalityError, match="1 observed entities into 3 goal entities"):
        make(name).plan(problem)


def test_gradient_at_least_as_good_as_sampling_at_equal_samples():
    problem = analytic_problem()
    for n in (128,):
        grad = make("exhaustive", num_samples=n, iterations=100, halving_points=[]).plan(problem)
        samp = make("sampling", num_samples=n, iterations=100).plan(problem)
        assert grad.info["evaluations"] == samp.info["evaluations"]
        assert grad.score >= samp.score - 1e-3, (n, grad.score, samp.score)


def test_successive_halving_spends_less_and_still_solves():
    problem = analytic_problem()
    full = make("exhaustive", num_samples=256, iterations=100, halving_points=[]).plan(problem)
    half = make("exhaustive", num_samples=256, iterations=100).plan(problem)
    assert half.info["evaluations"] < 0.6 * full.info["evaluations"]
    assert half.skills == OPTIMAL_SKELETON and half.score > 0.5


def test_max_horizon_searches_every_length():
    # goal reachable in 2 steps (split, move): the 1..3-step search returns a plan of the best length
    goal = torch.tensor([[0.6, 0.0, 0.75, 0.05, 0.5], [0.4, 0.0, 0.45, 0.05, 0.5]])
    problem = analytic_problem(horizon=3, goal=goal)
    planner = make("exhaustive", num_samples=128, iterations=100, max_horizon=3)
    plan = planner.plan(problem)
    assert plan.info["sequences"] == 1 + 4 + len(problem.skeletons())  # 1 step: split; 2 steps: 4; 3 steps: 12
    assert plan.horizon in (2, 3) and plan.score > 0.5
    with pytest.raises(CardinalityError, match="1 to 2 skills"):
        make("exhaustive", max_horizon=2).plan(analytic_problem(goal=torch.full((4, 5), 0.5)))


def test_receding_horizon_slides_over_a_longer_skeleton():
    # 4 steps with a window of 3: the first window is a partial problem (scored against the goal)
    skeleton = (*OPTIMAL_SKELETON, "move")
    problem = dataclasses.replace(analytic_problem(horizon=4), skeleton=skeleton)
    plan = make("receding_horizon", num_samples=128, iterations=100, window=3, halving_points=[]).plan(problem)
    check_plan(plan, problem)
    assert plan.skills == skeleton and len(plan.info["stages"]) == 4
    assert plan.final_cost < 0.01 and plan.score > 0.5


def test_config_switch_builds_each_planner():
    for name in PLANNERS:
        cfg = load_config([f"planner={name}", "planner.num_samples=2000", "planner.lr=0.02"])
        planner = get_plugins().planners.create(name, section(cfg, "planner"))
        assert planner.cfg.num_samples == 2000 and planner.cfg.lr == 0.02


@pytest.mark.parametrize("name", ["exhaustive", "sampling"])
def test_refinement_searches_the_best_sequences_again_and_keeps_the_better(name):
    problem = analytic_problem(seed=3)
    plain = make(name, num_samples=32, iterations=20, refine_sequences=0).plan(problem)
    refined = make(name, num_samples=32, iterations=20, refine_sequences=2).plan(problem)
    rows0, rows = plain.info["per_sequence"], refined.info["per_sequence"]
    # the first round draws the same candidates: the two refined rows are its two best sequences
    top2 = sorted(range(len(rows0)), key=lambda i: -rows0[i]["score"])[:2]
    assert [i for i, r in enumerate(rows) if r.get("refined")] == sorted(top2)
    for r0, r in zip(rows0, rows):
        assert r["score"] >= r0["score"]  # a refined sequence keeps the better of its two rounds
        assert r["samples"] == r0["samples"] * (2 if r.get("refined") else 1)  # left at the end of each round
    assert refined.info["samples"] == plain.info["samples"] + 2 * 32
    assert refined.score >= plain.score - 1e-9
    # with no more sequences than refine_sequences there is nothing to rank: the plain search
    many = make(name, num_samples=32, iterations=20, refine_sequences=len(rows0)).plan(problem)
    assert many.to_json(timings=False) == plain.to_json(timings=False)

