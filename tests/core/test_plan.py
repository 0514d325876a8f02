import pytest
import torch

from pasta.core import CardinalityError, InputError, Plan, SkillSpec, enumerate_skeletons, kept_indices
from pasta.plugins.analytic import ReferencePlanner, analytic_problem

CUT, PUSH, ROLL = SkillSpec("cut", 1, 2, "knife"), SkillSpec("push", 1, 1, "pusher"), SkillSpec("roll", 1, 1, "roller")


def test_crs_enumeration_keeps_the_twelve_sequences_with_one_cut():
    seqs = enumerate_skeletons([CUT, PUSH, ROLL], 3, 1, 2)
    assert len(seqs) == 12 and all(s.count("cut") == 1 for s in seqs)
    assert seqs == sorted(seqs, key=lambda s: [["cut", "push", "roll"].index(n) for n in s])


def test_enumeration_respects_entities_available():
    merge = SkillSpec("merge", 2, 1, "gripper")
    assert enumerate_skeletons([merge, CUT], 2, 1, 1) == [("cut", "merge")]


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
