"""One perceive -> plan -> check path for `pasta plan`, `pasta run` and `pasta eval`: a plan that fails its
checks is refused by all three (exit 2, nothing executed or written), and a planner plugin that raises or
returns a wrong type is named with its distribution (exit 1)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pasta.cli import main
from pasta.core import Plan, Planner, PluginRuntimeError
from pasta.core.errors import InputError
from pasta.core.plan import PlanStep, as_latents
from pasta.plugins import hookimpl, registry
from pasta.plugins.analytic import AnalyticPlugin, analytic_problem
from pasta.planning import LatentPlannerConfig


class RaisingPlanner(Planner):
    """A planner plugin with a bug."""

    def plan(self, problem):
        raise ZeroDivisionError("division by zero in the beam")


class DictPlanner(RaisingPlanner):
    """Returns a dict where a Plan belongs."""

    def plan(self, problem):
        return {"skills": ["move"]}


class NanPlanner(RaisingPlanner):
    """Returns a Plan whose score is NaN."""

    def plan(self, problem):
        u = problem.obs[0].tolist()
        step = PlanStep(problem.skills[0].name, (0,), as_latents([u]), 1.0, as_latents([u] + problem.obs[1:].tolist()))
        return Plan((step,), as_latents(problem.obs), as_latents(problem.goal), 0.0, math.nan, "nan_plan", problem.seed)


class FaultyPlanners:
    @hookimpl
    def pasta_register_planners(self, register):
        for name, cls in (("raising", RaisingPlanner), ("dict_plan", DictPlanner), ("nan_plan", NanPlanner)):
            register(name=name, factory=f"{__name__}:{cls.__name__}", config=LatentPlannerConfig)


@pytest.fixture
def faulty(monkeypatch):
    plugins = registry.discover(extra={"analytic": AnalyticPlugin(), "faulty": FaultyPlanners()})
    monkeypatch.setattr(registry, "_cache", plugins)
    return plugins


@pytest.fixture
def never_executed(monkeypatch):
    import pasta.execute.episode as episode

    def refuse(*args, **kwargs):
        raise AssertionError("a refused plan was executed")

    monkeypatch.setattr(episode, "execute_plan", refuse)


def test_the_shared_function_names_a_failing_planner_and_refuses_a_nan_plan(faulty):
    from pasta.execute.episode import _plan

    problem = analytic_problem()
    with pytest.raises(PluginRuntimeError, match=r"planner 'raising' \(plugin 'faulty' from \(in-process\)\) raised "
                                                 r"ZeroDivisionError: division by zero in the beam"):
        _plan(faulty.planners.create("raising"), problem, "raising")
    with pytest.raises(PluginRuntimeError, match="planner 'dict_plan' .* returned dict, not a pasta.core.Plan"):
        _plan(faulty.planners.create("dict_plan"), problem, "dict_plan")
    with pytest.raises(InputError, match="not valid"):
        _plan(faulty.planners.create("nan_plan"), problem, "nan_plan")


def _one_error(capsys, *words):
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert lines and all(w in err for w in words) and "Traceback" not in err, err
    return err


def _plan_args(tmp_path):
    from pasta.plugins.analytic import AnalyticEncoder

    p, enc = analytic_problem(), AnalyticEncoder()
    np.save(tmp_path / "obs.npy", enc.decode(p.obs, 300).reshape(-1, 3).numpy())
    np.save(tmp_path / "goal.npy", enc.decode(p.goal, 300).reshape(-1, 3).numpy())
    return [f"obs={tmp_path / 'obs.npy'}", f"goal={tmp_path / 'goal.npy'}", "encoder=analytic", "cost_model=analytic",
            "skills=split,move,flatten", "perception.min_points=10", "check.box_margin=1"]


@pytest.mark.parametrize("planner, code, words", [
    ("nan_plan", 2, ("not valid",)),
    ("raising", 1, ("planner 'raising'", "(in-process)", "ZeroDivisionError")),
    ("dict_plan", 1, ("planner 'dict_plan'", "returned dict")),
])
def test_pasta_plan_refuses_and_writes_nothing(tmp_path, faulty, capsys, planner, code, words):
    out = tmp_path / "out"
    assert main(["plan", *_plan_args(tmp_path), f"planner={planner}", f"out={out}"]) == code
    _one_error(capsys, *words)
    assert not (out / "plan.json").exists()


@pytest.mark.sim
@pytest.mark.parametrize("planner, code, words", [
    ("nan_plan", 2, ("not valid",)),
    ("raising", 1, ("planner 'raising'", "(in-process)", "ZeroDivisionError")),
])
def test_pasta_run_refuses_the_same_plans_before_executing(tmp_path, faulty, never_executed, capsys, planner, code,
                                                            words):
    assert main(["run", "task=push", "seed=1000", "skills=push", f"planner={planner}"]) == code
    _one_error(capsys, *words)


@pytest.mark.sim
def test_pasta_eval_refuses_the_same_plans_before_executing(tmp_path, faulty, never_executed, capsys):
    out = tmp_path / "eval"
    assert main(["eval", "task=push", "num=1", "skills=push", "planner=nan_plan", f"out={out}"]) == 2
    err = _one_error(capsys, "seed 1000: refused", "not valid")
    assert "1 of 1 episodes" in err and not list(out.glob("*.json"))
    assert main(["eval", "task=push", "num=1", "skills=push", "planner=raising", f"out={out}"]) == 1
    _one_error(capsys, "planner 'raising'", "ZeroDivisionError")


class StubPlanner:
    """Plans ``horizon`` nudges of 0.015 towards -x of the first observed entity; records its calls."""

    def __init__(self):
        self.calls = []

    def plan(self, problem):
        self.calls.append((len(problem.obs), problem.horizon))
        u = problem.obs[0].tolist()
        steps, state = [], [u]
        for _ in range(problem.horizon):
            u = [u[0], u[1], u[2] - 0.015, u[3], u[4]]
            steps.append(PlanStep("nudge", (0,), as_latents([u]), 1.0, as_latents([u] + state[1:])))
        return Plan(tuple(steps), as_latents(problem.obs), as_latents(problem.goal), 0.0, 1.0, "stub", problem.seed)


class ZeroCost:
    pass


@pytest.mark.sim
def test_run_episode_plans_once_and_executes_every_step(nudge, box_encoder):
    from pasta.config import ExecuteConfig, PerceptionConfig
    from pasta.execute.episode import run_episode
    from pasta.sim import SimConfig, Simulator, crs_dough

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=5)
    sim = Simulator(cfg)
    obs = sim.reset(crs_dough(cfg.n_particles, rng=5, floor_y=sim.floor_y, length=0.2))
    planner = StubPlanner()
    ep = run_episode(sim, obs.dough - np.array([0.03, 0, 0], np.float32), planner=planner, skills=[nudge],
                     encoder=box_encoder, cost=ZeroCost(), horizon=2, seed=0,
                     cfg=ExecuteConfig(controller="heuristic", idle_steps=1),
                     perception=PerceptionConfig(num_points=100), check=None)
    assert planner.calls == [(1, 2)]  # planned once: execution is open loop
    assert [s.skill for s in ep.result.steps] == ["nudge", "nudge"] and [s.ended for s in ep.result.steps] == ["done"] * 2
    assert ep.result.normalized_improvement > 0
