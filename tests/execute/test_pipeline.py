"""`pasta run` plumbing: argument splitting, and perceive -> plan -> execute with a stub planner (closed loop)."""

import numpy as np
import pytest

from pasta.commands.run import split_overrides
from pasta.config.overrides import build
from pasta.execute import ExecuteConfig
from pasta.core.errors import ConfigError
from pasta.core.plan import Plan, PlanStep, as_latents
from pasta.plugins import get_plugins


def test_split_overrides():
    own, exe, rest = split_overrides(["task=crs", "seed=3", "controller=heuristic", "execute.max_steps=20",
                                      "execute.closed_loop=true", "planner=sampling", "log=r.mcap"])
    assert own == {"task": "crs", "log": "r.mcap"}
    assert exe == {"controller": "heuristic", "max_steps": "20", "closed_loop": "true"}
    assert rest == ["seed=3", "planner=sampling"]
    typed = build(ExecuteConfig, exe, command="pasta run")
    assert (typed.controller, typed.max_steps, typed.closed_loop) == ("heuristic", 20, True)
    with pytest.raises(ConfigError, match="max_steps"):
        split_overrides(["execute.max_step=3"])
    with pytest.raises(ConfigError, match="max_steps.*could not be converted to Integer"):
        build(ExecuteConfig, split_overrides(["execute.max_steps=abc"])[1])


class StubPlanner:
    """Plans `horizon` nudges of 0.015 towards -x from the first observed entity; records its calls."""

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


def closed_loop_episode(planner, nudge, box_encoder):
    """Two planned nudges of a small dough towards a goal 3 cm to the left, re-planned after the first."""
    from pasta.execute import ExecuteConfig
    from pasta.execute.pipeline import run_episode
    from pasta.sim import SimConfig, Simulator, crs_dough

    cfg = SimConfig(n_grid=32, max_particles=1500, n_particles=1500, obs_points=300, seed=5)
    sim = Simulator(cfg, tools=get_plugins().simulated_tools())
    obs = sim.reset(crs_dough(cfg.n_particles, rng=5, floor_y=sim.floor_y, length=0.2))
    return run_episode(sim, obs.dough - np.array([0.03, 0, 0], np.float32), planner=planner, skills=[nudge],
                       encoder=box_encoder, cost=ZeroCost(), horizon=2, seed=0,
                       cfg=ExecuteConfig(controller="heuristic", idle_steps=1, decode_points=100, closed_loop=True))


@pytest.mark.sim
def test_run_episode_closed_loop_replans_after_each_step(nudge, box_encoder):
    planner = StubPlanner()
    ep = closed_loop_episode(planner, nudge, box_encoder)
    assert planner.calls == [(1, 2), (1, 1)]  # planned once, re-planned once for the last step
    assert [s.skill for s in ep.result.steps] == ["nudge", "nudge"] and len(ep.result.plans) == 2
    assert ep.result.normalized_improvement > 0


class CountChangesPlanner(StubPlanner):
    """Plans once; every re-plan finds no sequence for the observed pieces (as a skeleton that no longer fits)."""

    def plan(self, problem):
        if self.calls:
            from pasta.core.errors import CardinalityError

            self.calls.append((len(problem.obs), problem.horizon))
            raise CardinalityError("skeleton ['nudge'] cannot turn 2 observed entities into 1 goal entities")
        return super().plan(problem)


@pytest.mark.sim
def test_closed_loop_runs_the_plan_on_when_a_replan_finds_no_sequence(nudge, box_encoder):
    planner = CountChangesPlanner()
    ep = closed_loop_episode(planner, nudge, box_encoder)
    assert planner.calls == [(1, 2), (1, 1)]  # the re-plan was asked and failed
    assert [s.skill for s in ep.result.steps] == ["nudge", "nudge"]  # the first plan's second step still ran
    assert len(ep.result.plans) == 1 and len(ep.result.replan_errors) == 1
    assert "after step 0" in ep.result.replan_errors[0] and "cannot turn" in ep.result.replan_errors[0]
