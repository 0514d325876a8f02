"""The prefix_beam planner: horizons, cardinality pruning, bounded work per depth, config checks."""

from __future__ import annotations

import pytest

from pasta.config import load_config
from pasta.core import check_skeleton
from pasta.core.errors import ConfigError
from pasta.plugins import get_plugins
from pasta.testing import analytic_problem, configured

SMALL = {"polish": 0, "num_samples": 16, "iterations": 20, "prefix_samples": 8, "prefix_iterations": 10}


def _planner(**over):
    return configured(get_plugins().planners, "prefix_beam", {**SMALL, **over})


def _specs(problem):
    return [s.spec for s in problem.skills]


def test_default_plans_exactly_h_steps_and_only_consistent_sequences():
    problem = analytic_problem(horizon=4)
    plan = _planner().plan(problem)
    assert len(plan.skills) == 4, plan.skills
    for row in plan.info["per_sequence"]:  # the complete sequences the final search optimised
        assert len(row["skills"]) == 4
        check_skeleton(row["skills"], _specs(problem), 1, 2)  # raises if cardinality-inconsistent


def test_max_horizon_considers_every_length_up_to_n():
    problem = analytic_problem(horizon=3)
    plan = _planner(final=50, max_horizon=4).plan(problem)
    lengths = {len(row["skills"]) for row in plan.info["per_sequence"]}
    assert lengths <= {1, 2, 3, 4} and len(lengths) > 1, lengths
    for row in plan.info["per_sequence"]:
        check_skeleton(row["skills"], _specs(problem), 1, 2)
    assert 1 <= len(plan.skills) <= 4


def test_work_per_depth_is_bounded_by_width_counts_and_skills():
    problem = analytic_problem(horizon=5)
    width = 2
    plan = _planner(width=width, max_horizon=5).plan(problem)
    stages = plan.info["beam"]["stages"]
    assert [s["depth"] for s in stages] == [1, 2, 3, 4, 5]
    n_skills = len(problem.skills)
    for prev, stage in zip(stages, stages[1:]):
        # every kept prefix of the previous depth is extended by at most every skill
        assert stage["expanded"] <= len(prev["kept"]) * n_skills
    for stage in stages:
        counts = {}
        for skills in stage["kept"]:
            k = 1 + sum(s.delta for s in _specs(problem) for name in skills if s.name == name)
            counts[k] = counts.get(k, 0) + 1
        assert all(v <= width for v in counts.values()), counts  # at most `width` per entity count
    assert plan.info["beam"]["prefixes"] == sum(s["expanded"] for s in stages)
    assert plan.info["beam"]["prefix_searches"] == sum(s["searches"] for s in stages) <= sum(len(s["kept"]) for s in stages)


def test_same_seed_same_plan():
    a = _planner().plan(analytic_problem(seed=3))
    b = _planner().plan(analytic_problem(seed=3))
    assert a.to_json(timings=False) == b.to_json(timings=False)


@pytest.mark.parametrize("key", ["width", "final", "window", "prefix_samples", "max_horizon", "polish", "polish_top"])
def test_bad_settings_name_the_key(key):
    with pytest.raises(ConfigError, match=f"planner.{key}"):
        load_config(["planner=prefix_beam", f"planner.{key}={-1 if key in ('max_horizon', 'polish') else 0}"])


def test_search_reports_each_sequences_best_candidate():
    import torch

    from pasta.planning import LatentPlannerConfig, build_plan, search

    problem = analytic_problem()
    sequences = [("split", "move", "flatten"), ("split", "flatten", "move"), ("move", "split", "flatten")]
    cfg = LatentPlannerConfig(num_samples=16, iterations=10, clearance_weight=0.0)
    res = search(problem, sequences, cfg, torch.Generator().manual_seed(0))
    assert [b[0] for b in res.best] == sequences
    scores = [b[3] for b in res.best]
    assert [round(r["score"], 6) for r in res.per_sequence] == [round(x, 6) for x in scores]
    winner = res.best[scores.index(max(scores))]
    assert winner[0] == res.skeleton and winner[1] == res.attention and max(scores) == res.score
    for skeleton, attention, subgoals, score in res.best:  # each candidate re-evaluates to its score
        plan = build_plan(problem, skeleton, attention, subgoals, planner="t", cost_weight=cfg.cost_weight)
        assert abs(plan.score - score) < 1e-4 * max(1.0, score), (skeleton, plan.score, score)


def test_deleted_finish_modes_are_unknown_keys():
    with pytest.raises(ConfigError, match="unknown config key 'planner.finish'"):
        load_config(["planner=prefix_beam", "planner.finish=receding"])


def test_neighbours_are_every_sequence_one_edit_away():
    from pasta_planner_prefix_beam.planner import _neighbours

    got = _neighbours(("cut", "push"), ["cut", "push", "roll"])
    assert len(got) == len(set(got)) and ("cut", "push") not in got
    assert ("push", "cut", "push") in got and ("cut", "push", "roll") in got  # insertions
    assert ("cut",) in got and ("push",) in got  # deletions
    assert ("cut", "roll") in got and ("roll", "push") in got  # substitutions
    assert ("push", "cut") in got  # the swap
    assert all(abs(len(n) - 2) <= 1 for n in got)
    assert _neighbours(("push", "push"), ["push"]) == [("push", "push", "push"), ("push",)]  # no self-swap


def test_polish_from_one_final_sequence_reaches_exhaustives_plan():
    """With every searched sequence's neighbours searched (polish_top larger than the space), the local
    search covers every complete sequence, so with sequence draws it picks exactly exhaustive's plan."""
    problem = analytic_problem(horizon=3, seed=2)
    over = {"num_samples": 16, "iterations": 20, "draws": "sequence", "max_horizon": 3}
    reference = configured(get_plugins().planners, "exhaustive", over).plan(problem)
    plan = _planner(**over, final=1, polish=10, polish_top=1000).plan(problem)
    assert tuple(plan.skills) == tuple(reference.skills)
    assert plan.score == pytest.approx(reference.score, abs=1e-5)
    rounds = plan.info["polish"]
    assert rounds and all(r["searched"] > 0 for r in rounds)
    assert 1 + sum(r["searched"] for r in rounds) == reference.info["sequences"]  # each searched once
    unpolished = _planner(**over, final=1, polish=0).plan(problem)
    assert "polish" not in unpolished.info


def test_polish_stops_at_a_local_optimum():
    problem = analytic_problem(horizon=3, seed=2)
    plan = _planner(draws="sequence", max_horizon=3, final=1, polish=50).plan(problem)
    rounds = plan.info["polish"]
    assert len(rounds) < 50  # ended because the best two had no unsearched neighbour left
    scores = [r["score"] for r in rounds]
    assert scores == sorted(scores)  # the best found never gets worse


def test_no_searched_sequence_joins_what_it_cut():
    """With a 2 -> 1 skill among the candidates, a problem whose count only grows (1 -> 2) searches the same
    sequences as without it, in prefix_beam and exhaustive alike (the count moves only toward the goal's)."""
    import dataclasses

    import torch

    from pasta.core import PlanningProblem, SkillSpec
    from pasta.testing._analytic import MoveSkill

    class MergeSkill(MoveSkill):
        spec = SkillSpec("merge", 2, 1, "hand", "analytic test skill: two pieces into one")

        def feasibility(self, u_in, u_out):
            self._check_tuple(u_in, u_out)
            return torch.exp(-(u_out[:, 0, :2] - u_in[:, 0, :2]).pow(2).sum(-1))

    base = analytic_problem(horizon=3)
    problem = PlanningProblem(base.obs, base.goal, [*base.skills, MergeSkill()], base.encoder, base.cost,
                              horizon=3, seed=base.seed)
    assert problem.skeletons() == base.skeletons()
    plan = _planner(final=50).plan(problem)
    assert all("merge" not in row["skills"] for row in plan.info["per_sequence"])
    shrink = dataclasses.replace(problem, obs=base.goal, goal=base.obs, horizon=1)  # 2 -> 1: the merge alone
    assert shrink.skeletons() == [("merge",)]
    assert _planner().plan(shrink).skills == ("merge",)
