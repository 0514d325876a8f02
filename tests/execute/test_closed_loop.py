"""The closed loop's test (does the plan still fit?) and its warm start, on hand-made plans; and a crs run
under each kind of disturbance that logs it, re-plans, and replays exactly."""

from __future__ import annotations

import numpy as np
import pytest

from pasta.core import CardinalityError, InputError, PlanningProblem
from pasta.core.plan import Plan, PlanStep
from pasta.execute.loop import (extra_pieces, join_labels, place_matters, plan_fit, predicted_set,
                                warm_start_sequences)

Z = 2  # shape-code size of the hand-made latents: (z0, z1, x, y, z)


def _latent(x, z=0.5, y=0.03):
    return [0.0, 0.0, x, y, z]


def _cut_then_push():
    """One piece at x 0.5 -> cut into x 0.45 / 0.55 -> push the first to x 0.3."""
    initial = [_latent(0.5)]
    cut = PlanStep("cut", (0,), [_latent(0.45), _latent(0.55)], 0.9, [_latent(0.45), _latent(0.55)])
    push = PlanStep("push", (0,), [_latent(0.3)], 0.9, [_latent(0.3), _latent(0.55)])
    return Plan((cut, push), initial, [_latent(0.3), _latent(0.55)], 0.0, 1.0, "test", 0)


def _observed(*xs):
    rng = np.random.default_rng(0)
    dough = np.concatenate([np.array([x, 0.03, 0.5]) + rng.normal(0, 0.004, (50, 3)) for x in xs])
    labels = np.repeat(np.arange(len(xs)), 50)
    return dough, labels


def test_the_plan_fits_when_pieces_are_where_it_expects_them():
    dough, labels = _observed(0.455, 0.55)
    fit = plan_fit(_cut_then_push(), {0}, dough, labels, Z, 0.03)
    assert fit.fits and fit.distance < 0.01 and (fit.observed, fit.expected) == (2, 2)


def test_a_moved_piece_or_another_count_makes_it_not_fit_and_says_why():
    dough, labels = _observed(0.45, 0.60)  # the piece that stays where the cut left it moved 5 cm
    fit = plan_fit(_cut_then_push(), {0}, dough, labels, Z, 0.03)
    assert not fit.fits and "cm from where the plan expects it" in fit.reason and 0.045 < fit.distance < 0.055
    dough, labels = _observed(0.40, 0.50, 0.60)
    fit = plan_fit(_cut_then_push(), {0}, dough, labels, Z, 0.03)
    assert not fit.fits and fit.reason == "3 pieces observed, the plan expects 2"


def test_a_piece_that_a_later_push_places_may_lie_anywhere_one_that_a_roll_keeps_may_not():
    dough, labels = _observed(0.38, 0.55)  # output 0 of the cut lies 7 cm off; the push will carry it
    fit = plan_fit(_cut_then_push(), {0}, dough, labels, Z, 0.03)
    assert fit.fits and "stay where they are lie within" in fit.reason
    rolled = _cut_then_push()
    rolled = Plan((rolled.steps[0], PlanStep("roll", (0,), [_latent(0.45)], 0.9, [_latent(0.45), _latent(0.55)])),
                  rolled.initial, rolled.goal, 0.0, 1.0, "test", 0)
    keeps = {"roll": True}.get
    assert place_matters(rolled, 1, lambda n: bool(keeps(n))) == [True, True]
    assert place_matters(_cut_then_push(), 1, lambda n: False) == [False, True]
    assert not plan_fit(rolled, {0}, dough, labels, Z, 0.03, keeps_position=lambda n: bool(keeps(n))).fits


def test_where_the_executor_aimed_a_piece_overrides_its_latent():
    plan = _cut_then_push()
    dough, labels = _observed(0.45, 0.60)
    aimed = {(0, 1): np.array([0.60, 0.03, 0.5])}  # the controller was told to put output 1 at x 0.60
    assert plan_fit(plan, {0}, dough, labels, Z, 0.03, aimed).fits
    assert np.allclose(predicted_set(plan, {0}, Z, aimed)[:, 0], [0.45, 0.60])
    assert np.allclose(predicted_set(plan, {0, 1}, Z)[:, 0], [0.3, 0.55])


def test_out_of_order_steps_make_no_prediction_and_keep_the_plan():
    dough, labels = _observed(0.3, 0.55)
    fit = plan_fit(_cut_then_push(), {1}, dough, labels, Z, 0.03)
    assert fit.fits and "out of plan order" in fit.reason


def test_an_extra_piece_joins_the_piece_whose_place_it_shares():
    # the cut's output 1 (x 0.55) was split in two: halves at 0.53 and 0.57; output 0 lies at 0.45
    dough, labels = _observed(0.45, 0.53, 0.57)
    pairs = extra_pieces(_cut_then_push(), {0}, dough, labels, Z)
    assert len(pairs) == 1 and set(pairs[0]) == {1, 2}
    assert extra_pieces(_cut_then_push(), {0}, *_observed(0.45, 0.55), Z) == []  # counts agree: nothing extra
    index = np.arange(len(dough))
    known = index[labels != 2]  # piece 2's particles were not there before the step: a lump, new dough
    assert extra_pieces(_cut_then_push(), {0}, dough, labels, Z, index=index, known=known) == []
    assert len(extra_pieces(_cut_then_push(), {0}, dough, labels, Z, index=index, known=index)) == 1


def test_joined_pieces_are_one_entity_by_particle_identity_in_decomposition_order():
    dough, labels = _observed(0.45, 0.53, 0.57)
    index = np.arange(len(dough)) + 1000  # particle ids of the observed points
    joined = [index[labels >= 1]]
    out = join_labels(dough, labels, index, joined)
    assert out.max() == 1 and np.array_equal(out, np.where(labels >= 1, 1, 0))
    flipped = join_labels(dough, labels, index, [index[labels <= 1]])  # 0 and 1 joined: the centroid order holds
    assert np.array_equal(flipped, np.where(labels <= 1, 0, 1))
    assert np.array_equal(join_labels(dough, labels, index, []), labels)


def test_a_stray_particle_of_a_joined_group_does_not_join_the_piece_it_is_counted_with():
    # crs seed 1000 under a split: one particle of the split piece's halves was counted with the cut piece
    # once the halves moved (a noise point joins its nearest piece), and the whole scene became one entity
    dough, labels = _observed(0.45, 0.53, 0.57)
    index = np.arange(len(dough)) + 1000
    group = index[labels >= 1]
    stray = np.flatnonzero(labels >= 1)[0]
    labels_now = labels.copy()
    labels_now[stray] = 0  # the perception now counts that particle with piece 0
    out = join_labels(dough, labels_now, index, [group])
    assert out.max() == 1  # two entities: piece 0 (with the stray point) and the joined halves
    assert np.array_equal(out[labels >= 1][1:], np.ones(int((labels >= 1).sum()) - 1, np.int64))
    assert (out[labels == 0] == 0).all()


def test_warm_start_keeps_the_remaining_sequence_first_and_adds_one_step_anywhere():
    seqs = warm_start_sequences(["push", "roll"], ["cut", "push", "roll"])
    assert seqs[0] == ("push", "roll")
    assert ("cut", "push", "roll") in seqs and ("push", "roll", "cut") in seqs and ("push", "cut", "roll") in seqs
    assert all(len(s) in (2, 3) for s in seqs) and len(seqs) == len(set(seqs))


def test_a_problem_searches_the_candidates_that_reach_the_goal_count(box_encoder):
    from types import SimpleNamespace

    import torch

    from pasta.core import SkillSpec

    skills = [SimpleNamespace(name="cut", spec=SkillSpec("cut", 1, 2, "knife")),
              SimpleNamespace(name="push", spec=SkillSpec("push", 1, 1, "pusher"))]
    obs, goal = torch.zeros(1, box_encoder.latent_dim), torch.zeros(2, box_encoder.latent_dim)
    problem = PlanningProblem(obs, goal, skills, box_encoder, None, 1, candidates=[("push",), ("cut",), ("cut", "push")])
    assert problem.sequences_given and problem.skeletons() == [("cut",), ("cut", "push")]
    with pytest.raises(CardinalityError, match="none of the 1 candidate"):
        PlanningProblem(obs, goal, skills, box_encoder, None, 1, candidates=[("push",)]).skeletons()
    with pytest.raises(InputError, match="not both"):
        PlanningProblem(obs, goal, skills, box_encoder, None, 1, skeleton=("cut",), candidates=[("cut",)])
    with pytest.raises(InputError, match="unknown: \\['roll'\\]"):
        PlanningProblem(obs, goal, skills, box_encoder, None, 1, candidates=[("roll",)])


def test_the_summary_of_a_replanned_run_shows_each_executed_step_its_plan_and_the_disturbance(box_encoder):
    from types import SimpleNamespace

    from pasta.execute.executor import StepInfo, StepSnapshot
    from pasta.execute.summary import summary_steps

    first = _cut_then_push()
    second = Plan((PlanStep("push", (1,), [_latent(0.7)], 0.8, [_latent(0.7), _latent(0.3)]),
                   PlanStep("push", (1,), [_latent(0.3)], 0.7, [_latent(0.3), _latent(0.7)])),
                  first.steps[0].state, first.goal, 0.0, 1.0, "test", 0)
    infos = [StepInfo(0, "cut", (0,), (0,), 1, 50, 40, "done", 1, 0.1, 0.4, 1.0, 0, 0),
             StepInfo(1, "push", (1,), (1,), 2, 25, 30, "done", 1, 0.05, 0.7, 1.0, 0, 1)]
    dough = np.zeros((10, 3), np.float32)
    result = SimpleNamespace(plans=[first, second], steps=infos, snapshots=[StepSnapshot(dough)] * 2,
                             disturbance={"kind": "shift", "applied": True}, start_tools=[], end_tools=[])
    subgoals, executed, _, _ = summary_steps(first, result, box_encoder, num_points=20)
    titles = [t for t, _ in subgoals]
    assert titles == ["1. cut  (plan f=0.90)", "2. push  (plan f=0.80, re-plan 1)", "3. push  (plan f=0.70, re-plan 1)"]
    assert executed[0] is not None and "then disturbed: shift" in executed[0].note
    assert executed[1] is not None and executed[2] is None  # the re-plan's second step did not run
    assert np.allclose(subgoals[1][1][0].mean(0)[0], 0.7, atol=0.01)  # drawn from the re-plan's sub-goal


@pytest.mark.parametrize("kind", ["lump", "merge"])
def test_a_disturbed_closed_loop_run_logs_what_happened_and_replays_exactly(tmp_path, capsys, kind):
    """A short crs run (tests/pasta_runs.py) with a lump (the particle count changes) or a merge (two pieces
    become one): the run prints the disturbance and each loop decision, the log holds them, and replay
    re-simulates the run with the disturbance applied at its step: zero deviation from the logged final state."""
    from pasta_runs import RUN

    from pasta.cli import main
    from pasta.io import RunReader
    from pasta.io.replay import verify_run

    log = tmp_path / "run.mcap"
    run = [a for a in RUN if not a.startswith("execute.retries=")]  # a cut that needs its retry separates
    picture = tmp_path / "run.png"
    assert main([*run, f"disturb={kind}", "execute.loop=closed", f"log={log}", f"summary={picture}"]) == 0
    out = capsys.readouterr().out
    assert f"disturbance ({kind})" in out and "closed loop: " in out
    assert picture.stat().st_size > 10_000
    reader = RunReader(log)
    decisions = [m for _, m in reader.messages("/loop")]
    assert decisions and all(d["decision"] in ("kept", "replanned") and d["reason"] for d in decisions)
    marks = [m for _, m in reader.messages("/actions") if "disturb" in m]
    assert len(marks) == 1 and marks[0]["disturb"] in reader.attachment_names()
    if kind == "merge":  # one piece where the plan expects two: it no longer fits, and the loop re-planned
        assert decisions[0]["decision"] == "replanned"
        assert decisions[0]["reason"] == "1 pieces observed, the plan expects 2"
        assert len([1 for _ in reader.messages("/plan")]) >= 2
    ok, deviation = verify_run(reader, 0.0)
    assert ok and deviation == 0.0
    if kind == "lump":  # without the disturbance the replay would not even have the particles
        import io

        from pasta.sim import SimState

        final = SimState.load(io.BytesIO(reader.attachment("final_state.npz")))
        initial = SimState.load(io.BytesIO(reader.attachment("initial_state.npz")))
        assert len(final.x) > len(initial.x)


def test_a_misspelt_disturbance_or_loop_fails_before_any_work_with_a_suggestion(capsys):
    from pasta.cli import main

    assert main(["run", "task=crs", "disturb=shfit"]) == 2
    assert "did you mean 'shift'" in capsys.readouterr().err
    assert main(["eval", "task=crs", "execute.loop=closd"]) == 2
    assert "did you mean 'closed'" in capsys.readouterr().err
