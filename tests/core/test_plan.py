import pytest
import torch

from pasta.core import CardinalityError, InputError, Plan, SkillSpec, check_skeleton, enumerate_skeletons, kept_indices
from pasta.testing import ReferencePlanner, analytic_problem

CUT, PUSH, ROLL = SkillSpec("cut", 1, 2, "knife"), SkillSpec("push", 1, 1, "pusher"), SkillSpec("roll", 1, 1, "roller")


def test_crs_enumeration_keeps_the_twelve_sequences_with_one_cut():
    seqs = enumerate_skeletons([CUT, PUSH, ROLL], 3, 1, 2)
    assert len(seqs) == 12 and all(s.count("cut") == 1 for s in seqs)
    assert seqs == sorted(seqs, key=lambda s: [["cut", "push", "roll"].index(n) for n in s])


def test_enumeration_respects_entities_available():
    merge = SkillSpec("merge", 2, 1, "gripper")
    assert enumerate_skeletons([merge, CUT, PUSH], 2, 3, 2) == [("merge", "push"), ("push", "merge")]


def test_enumeration_moves_the_count_only_toward_the_goal():
    """No searched sequence cuts a piece only to join it again (or joins pieces only to cut them): a join
    skill adds no sequence to a task whose count only grows, and a given skeleton may still do so."""
    merge = SkillSpec("merge", 2, 1, "gripper")
    assert enumerate_skeletons([CUT, PUSH, ROLL, merge], 3, 1, 2) == enumerate_skeletons([CUT, PUSH, ROLL], 3, 1, 2)
    with pytest.raises(CardinalityError, match="only by a detour.*give the skeleton"):
        enumerate_skeletons([merge, CUT], 2, 1, 1)  # cut then merge: back where it started
    assert ("cut", "merge", "cut") not in enumerate_skeletons([merge, CUT, PUSH], 3, 1, 2)
    check_skeleton(("cut", "merge"), [CUT, merge], 1, 1)  # a skeleton the user gives is only count-checked


def test_cardinality_error_names_counts_and_cardinalities():
    with pytest.raises(CardinalityError, match=r"turns 1 observed entities into 4 goal entities.*cut 1->2, push 1->1"):
        enumerate_skeletons([CUT, PUSH], 2, 1, 4)


def test_kept_indices():
    assert kept_indices(4, (2, 0)) == (1, 3)
    with pytest.raises(InputError, match="distinct indices"):
        kept_indices(2, (0, 0))
    with pytest.raises(InputError, match="distinct indices"):
        kept_indices(2, (2,))


def test_problem_validates_inputs():
    with pytest.raises(InputError, match="latent size 4, expected D = 5"):
        analytic_problem(goal=torch.zeros(2, 4))
    with pytest.raises(InputError, match="NaN"):
        analytic_problem(goal=torch.full((2, 5), float("nan")))


def test_plan_json_round_trip_and_summary():
    plan = ReferencePlanner().plan(analytic_problem())
    text = plan.to_json()
    again = Plan.from_json(text)
    assert again == plan and again.to_json() == text
    assert "timings" not in plan.to_json(timings=False)
    assert "split" in plan.summary()
    with pytest.raises(InputError, match="format_version"):
        Plan.from_json(text.replace('"format_version": 1', '"format_version": 99'))


def _replace(plan, **kw):
    import dataclasses

    return dataclasses.replace(plan, **kw)


def test_plans_with_nan_or_out_of_range_values_are_refused():
    """Issue 21: a NaN score or latent, a score outside [0, 1] never reaches a plan file."""
    import dataclasses

    plan = ReferencePlanner().plan(analytic_problem())
    assert plan.problems() == [] and plan.check() is plan
    nan = float("nan")
    bad_step = dataclasses.replace(plan.steps[1], feasibility=1.7,
                                   subgoal=tuple((nan,) * len(r) for r in plan.steps[1].subgoal))
    cases = [
        (_replace(plan, score=nan), "score is nan"),
        (_replace(plan, score=3.4), r"score 3.4 is outside \[0, 1\]"),
        (_replace(plan, final_cost=float("inf")), "final_cost is inf"),
        (_replace(plan, goal=((nan,) * 5,) + plan.goal[1:]), "goal has 1 of 2 latents with NaN"),
        (_replace(plan, steps=(plan.steps[0], bad_step) + plan.steps[2:]), r"step 2 \(move\) feasibility 1.7 .*"
                                                                         r"step 2 \(move\) subgoal has 1 of 1"),
    ]
    for bad, message in cases:
        assert bad.problems()
        with pytest.raises(InputError, match=message):
            bad.check()
        with pytest.raises(InputError, match="is not valid"):
            bad.to_json()
    with pytest.raises(InputError, match="strict JSON"):
        _replace(plan, info={"x": nan}).to_json()


def test_plan_files_are_strict_json():
    plan = ReferencePlanner().plan(analytic_problem())
    text = plan.to_json()
    assert "NaN" not in text and "Infinity" not in text
    with pytest.raises(InputError, match="not strict JSON: it contains NaN"):
        Plan.from_json(text.replace(f'"score": {plan.score!r}', '"score": NaN'))
    with pytest.raises(InputError, match="score 2 is outside"):
        Plan.from_json(text.replace(f'"score": {plan.score!r}', '"score": 2.0'))
    with pytest.raises(InputError, match="not valid JSON"):
        Plan.from_json(text[:-5])
    with pytest.raises(InputError, match="lacks the field 'steps'"):
        Plan.from_json(text.replace('"steps"', '"stepz"'))
