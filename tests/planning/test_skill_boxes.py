"""A skill's own centroid box (``Skill.output_box``): its sub-goals are drawn and kept at its own heights, on
the table plane in the union with the encoder's box; skills without one use the encoder's and plan exactly
as before."""

from __future__ import annotations

from types import SimpleNamespace

import pytest
import torch

from pasta.planning import build_plan, sample_candidates
from pasta.planning.batch import centroid_box, clamp_to_skill, training_boxes
from pasta.plugins import get_plugins
from pasta.plugins.analytic import analytic_problem
from pasta.plugins.checks import configured

# the analytic encoder's box is (0.1, 0, 0.1)-(0.9, 0.2, 0.9); "move" sets pieces down higher up, as a lift
# onto a raised board does
RAISED = ((0.3, 0.3, 0.4), (0.5, 0.5, 0.6))


def with_box(problem, name: str = "move", box=RAISED):
    problem.skill_map[name].feasibility_model = SimpleNamespace(output_box=box)  # the analytic skills ignore it
    return problem


def test_a_skill_with_a_box_uses_it_the_others_the_encoders():
    p = with_box(analytic_problem())
    assert centroid_box(p.encoder, p.skill_map["move"]) == ((0.1, 0.3, 0.1), (0.9, 0.5, 0.9))  # own y, union x/z
    assert centroid_box(p.encoder, p.skill_map["split"]) == (tuple(p.encoder.t_low), tuple(p.encoder.t_high))
    assert training_boxes(p.encoder, p.skills) == [((0.1, 0.0, 0.1), (0.9, 0.2, 0.9)), ((0.1, 0.3, 0.1), (0.9, 0.5, 0.9))]
    far = torch.tensor([[1.0, 0.0, 0.7, 0.9, 0.5]])  # y = 0.9: above both boxes
    low = torch.tensor([[1.0, 0.0, 0.7, 0.1, 0.5]])  # y = 0.1: below the raised box
    assert float(clamp_to_skill(far, p.encoder, p.skill_map["move"])[0, 3]) == pytest.approx(0.5)
    assert float(clamp_to_skill(low, p.encoder, p.skill_map["move"])[0, 3]) == pytest.approx(0.3)
    assert float(clamp_to_skill(far, p.encoder, p.skill_map["split"])[0, 3]) == pytest.approx(0.2)


def test_draws_fill_the_skills_box_and_leave_the_others_unchanged():
    plain = analytic_problem()
    boxed = with_box(analytic_problem())
    seqs = [("move",), ("flatten",), ("split", "move")]
    a = sample_candidates(plain.obs, plain.goal, seqs, plain.skill_map, plain.encoder, 256, torch.Generator().manual_seed(0))
    b = sample_candidates(boxed.obs, boxed.goal, seqs, boxed.skill_map, boxed.encoder, 256, torch.Generator().manual_seed(0))
    for ga, gb in zip(a.groups, b.groups):
        assert ga.t_low is None and gb.t_low is not None
        for si, seq in enumerate(seqs):
            rows = gb.seq == si
            if not bool(rows.any()):
                continue
            slots = [name for name in seq for _ in range(boxed.skill_map[name].n_out)]
            for j, name in enumerate(slots):
                ya, yb = ga.latents[rows, j, 3], gb.latents[rows, j, 3]
                if name == "move":  # spread over its own heights, above the encoder's 0.2
                    assert 0.3 - 1e-6 <= float(yb.min()) and float(yb.max()) <= 0.5 + 1e-6
                    assert float(yb.std()) > 0.04
                    # the table plane: the union with the encoder's box is the encoder's here: same draws
                    assert torch.equal(ga.latents[rows, j, 2], gb.latents[rows, j, 2])
                else:  # the very same draws as without any box
                    assert torch.equal(ya, yb)
            assert all(torch.equal(x, y) for x, y in zip(ga.inputs, gb.inputs))


@pytest.mark.parametrize("name", ["exhaustive", "sampling"])
def test_optimised_subgoals_stay_in_their_boxes(name):
    planner = configured(get_plugins().planners, name, {"iterations": 20, "num_samples": 32})
    # a goal piece high up: "move" can reach it, the encoder's box alone cannot hold it
    p = with_box(analytic_problem(goal=torch.tensor([[1.0, 0.0, 0.7, 0.45, 0.5]]), skeleton=("move",)))
    plan = planner.plan(p)
    y = float(torch.as_tensor(plan.steps[0].subgoal)[0, 3])
    assert 0.3 - 1e-6 <= y <= 0.5 + 1e-6  # above the encoder's box, inside the skill's
    same = build_plan(p, plan.skills, [s.inputs for s in plan.steps], [torch.as_tensor(s.subgoal) for s in plan.steps],
                      planner=name, cost_weight=planner.config.cost_weight, floor=planner.config.feasibility_floor)
    assert same.score == pytest.approx(plan.score)  # rollout clamps with the same box


def test_plans_without_boxes_are_unchanged():
    planner = configured(get_plugins().planners, "exhaustive", {"iterations": 10, "num_samples": 16})
    p = analytic_problem()
    p.skill_map["flatten"].feasibility_model = SimpleNamespace(output_box=None)
    assert planner.plan(p).to_json(timings=False) == planner.plan(analytic_problem()).to_json(timings=False)


def test_pieces_may_lie_in_any_one_box_not_in_their_hull():
    from pasta.execute.episode import check_training_box, latent_distances
    from pasta.core.errors import InputError

    p = with_box(analytic_problem())
    boxes = training_boxes(p.encoder, p.skills)
    raised = torch.tensor([[1.0, 0.0, 0.4, 0.4, 0.5]])  # inside the raised box only
    assert check_training_box(raised, p.encoder, "goal", 0.0, boxes=boxes) == []  # no flag: inside a box
    assert latent_distances(raised, p.encoder, boxes)[0]["t_outside"] == 0.0
    # between the heights of both boxes: inside their hull, outside each (0.07 above the encoder's, 0.03
    # under the raised one, the nearest)
    between = torch.tensor([[1.0, 0.0, 0.5, 0.27, 0.5]])
    with pytest.raises(InputError, match=r"0.030 out in y; box x 0.100..0.900, y 0.300..0.500.*nearest of 2"):
        check_training_box(between, p.encoder, "goal", 0.0, boxes=boxes)
    assert latent_distances(between, p.encoder, boxes)[0]["t_outside"] == pytest.approx(0.03, abs=1e-6)
    with pytest.raises(InputError, match="out in y"):  # the encoder's box alone, as without skill boxes
        check_training_box(raised, p.encoder, "goal", 0.0)
