"""``pasta.planning`` exports what a planner plugin is written with, documented, without importing torch early."""

from __future__ import annotations

import subprocess
import sys

import pytest
import torch

import pasta.planning
from pasta.core.errors import InputError
from pasta.testing import OPTIMAL_SKELETON, analytic_problem


@pytest.mark.parametrize("name", pasta.planning.__all__)
def test_every_export_resolves_and_is_documented(name):
    obj = getattr(pasta.planning, name)
    assert not name.startswith("_") and (obj.__doc__ or "").strip(), f"pasta.planning.{name} needs a docstring"


def test_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="has no attribute 'nope'"):
        pasta.planning.nope  # noqa: B018


def test_importing_the_package_and_planner_configs_does_not_import_torch():
    code = ("import sys, pasta.planning, pasta.planning.config\n"
            "import pasta_planner_exhaustive.config, pasta_planner_sampling.config\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] == 'torch'))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_attention_structures_enumerate_every_choice_per_step():
    problem = analytic_problem()
    structures = pasta.planning.attention_structures(problem, OPTIMAL_SKELETON)
    # split consumes 1 of 1, then move 1 of 2, then flatten 1 of 2
    assert structures == [[(0,), (0,), (0,)], [(0,), (0,), (1,)], [(0,), (1,), (0,)], [(0,), (1,), (1,)]]
    assert len(pasta.planning.attention_structures(problem, ("move",), start_size=3)) == 3
    with pytest.raises(InputError, match="consumes 1 entities of a set of 0"):
        pasta.planning.attention_structures(problem, ("move",), start_size=0)
    with pytest.raises(InputError, match="not one of the problem's skills"):
        pasta.planning.attention_structures(problem, ("cut",))


def test_a_planner_from_the_public_helpers_returns_a_conforming_plan():
    """Random search written only with pasta.planning's exports (what the README walks through): the plan that
    build_plan packages is the best candidate the rollout scored, and it passes the plan checker."""
    from pasta.planning import attention_structures, build_plan, plan_score, rollout
    from pasta.testing import check_plan

    problem = analytic_problem()
    gen = torch.Generator().manual_seed(problem.seed)
    best = None
    for skeleton in problem.skeletons():
        counts = [problem.skill_map[n].n_out for n in skeleton]
        for attention in attention_structures(problem, skeleton):
            latents = problem.encoder.sample_prior(64 * sum(counts), gen).reshape(64, sum(counts), -1)
            subgoals = list(torch.split(problem.encoder.clamp(latents), counts, dim=1))  # per step (B, M_h, D)
            with torch.no_grad():
                r = rollout(problem, skeleton, attention, subgoals)
                score = plan_score(r.feasibility, r.cost, cost_weight=1.0, floor=0.01)
            i = int(score.argmax())
            if best is None or float(score[i]) > best[0]:
                best = (float(score[i]), skeleton, attention, [s[i] for s in subgoals])
    plan = build_plan(problem, best[1], best[2], best[3], planner="toy", cost_weight=1.0, floor=0.01)
    check_plan(plan, problem, cost_weight=1.0)
    assert plan.skills == best[1] and abs(plan.score - best[0]) < 1e-5, (plan.skills, plan.score, best[:2])
