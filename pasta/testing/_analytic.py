"""An analytic planning problem with a known optimum, for testing planners without trained networks.

Entities have ``z = (size, flatness)`` and a centroid ``t``. Three fake skills have closed-form
feasibility:

- ``split`` (1 -> 2): sizes add up, flatness is kept, the halves stay around the original centroid
  and at most 0.2 apart;
- ``move`` (1 -> 1): any new centroid, shape unchanged;
- ``flatten`` (1 -> 1): flatness + 1 in place, only inside the spreading area ``x in [0.2, 0.3]``.

:func:`analytic_problem` starts from one piece at ``x = 0.7``; its goal is a piece of size 0.6 at
``x = 0.75`` and a flattened piece of size 0.4 at ``x = 0.25``. Within 3 steps the only way to reach it
is ``split -> move (the 0.4 piece) -> flatten (the same piece)`` (:data:`OPTIMAL_SKELETON`).

:class:`ReferencePlanner` solves it by brute force (every skeleton and attention structure, the
cross-entropy method over sub-goal latents); it exists to exercise
:class:`pasta.testing.PlannerContract` and is not meant for real problems.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass
from typing import Any

import torch

from pasta.core import CostModel, Encoder, Plan, Planner, PlanningProblem, Skill, SkillSpec, ToolSpec
from pasta.planning import LatentPlannerConfig, attention_structures, build_plan, log_objective, plan_score, rollout
from pasta.plugins.hookspecs import hookimpl

SIGMA = 0.1
OPTIMAL_SKELETON = ("split", "move", "flatten")
AREA_X = (0.2, 0.3)
_TEMPLATE_POINTS = 256


class AnalyticEncoder(Encoder):
    """Decodes ``u`` to a box-shaped cloud: half-width ``0.05 (1 + flat)``, half-height ``0.05 size / (1 + flat)^2``."""

    z_dim = 2
    t_low = (0.1, 0.0, 0.1)
    t_high = (0.9, 0.2, 0.9)

    def _template(self, n: int) -> torch.Tensor:
        g = torch.Generator().manual_seed(0)
        pts = torch.rand(n, 3, generator=g) * 2 - 1
        pts[:8] = torch.tensor(list(itertools.product((-1.0, 1.0), repeat=3)))  # corners make max() exact
        return pts

    def decode(self, latents: torch.Tensor, num_points: int) -> torch.Tensor:
        size, flat, t = latents[:, 0:1], latents[:, 1:2], latents[:, 2:]
        half_w = 0.05 * (1 + flat)
        half_h = 0.05 * size / (1 + flat) ** 2
        scale = torch.cat([half_w, half_h, half_w], -1)[:, None, :]
        return self._template(num_points)[None] * scale + t[:, None, :]

    def encode(self, points: torch.Tensor) -> torch.Tensor:
        t = (points.amax(1) + points.amin(1)) / 2
        half = (points.amax(1) - points.amin(1)) / 2
        flat = half[:, 0:1] / 0.05 - 1
        size = half[:, 1:2] / 0.05 * (1 + flat) ** 2
        return torch.cat([size, flat, t], -1)

    def sample_prior(self, n: int, generator: torch.Generator) -> torch.Tensor:
        z = torch.rand(n, 2, generator=generator) * 1.5
        low, high = torch.tensor(self.t_low), torch.tensor(self.t_high)
        t = low + torch.rand(n, 3, generator=generator) * (high - low)
        return torch.cat([z, t], -1)


class AnalyticCost(CostModel):
    """``0.1 ||z_a - z_b||^2 + ||t_a - t_b||^2``."""

    def pairwise(self, a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
        dz = (a[:, :, None, :2] - b[:, None, :, :2]).pow(2).sum(-1)
        dt = (a[:, :, None, 2:] - b[:, None, :, 2:]).pow(2).sum(-1)
        return 0.1 * dz + dt


def _gauss(r2: torch.Tensor) -> torch.Tensor:
    return torch.exp(-r2 / (2 * SIGMA**2))


class SplitSkill(Skill):
    spec = SkillSpec("split", 1, 2, "blade", "analytic test skill: one piece into two")

    def feasibility(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        self._check_tuple(u_in, u_out)
        a, b, c = u_out[:, 0], u_out[:, 1], u_in[:, 0]
        r2 = (a[:, 0] + b[:, 0] - c[:, 0]) ** 2 + (a[:, 1] - c[:, 1]) ** 2 + (b[:, 1] - c[:, 1]) ** 2
        r2 = r2 + ((a[:, 2:] + b[:, 2:]) / 2 - c[:, 2:]).pow(2).sum(-1)
        r2 = r2 + torch.relu((a[:, 2:] - b[:, 2:]).norm(dim=-1) - 0.2) ** 2
        return _gauss(r2)


class MoveSkill(Skill):
    spec = SkillSpec("move", 1, 1, "hand", "analytic test skill: translate a piece")

    def feasibility(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        self._check_tuple(u_in, u_out)
        return _gauss((u_out[:, 0, :2] - u_in[:, 0, :2]).pow(2).sum(-1))


class FlattenSkill(Skill):
    spec = SkillSpec("flatten", 1, 1, "press", "analytic test skill: flatten a piece inside the spreading area")

    def feasibility(self, u_in: torch.Tensor, u_out: torch.Tensor) -> torch.Tensor:
        self._check_tuple(u_in, u_out)
        i, o = u_in[:, 0], u_out[:, 0]
        r2 = (o[:, 0] - i[:, 0]) ** 2 + (o[:, 1] - i[:, 1] - 1) ** 2 + (o[:, 2:] - i[:, 2:]).pow(2).sum(-1)
        centre, half = sum(AREA_X) / 2, (AREA_X[1] - AREA_X[0]) / 2
        return _gauss(r2 + torch.relu((i[:, 2] - centre).abs() - half) ** 2)


def analytic_skills() -> list[Skill]:
    return [SplitSkill(), MoveSkill(), FlattenSkill()]


def analytic_problem(*, horizon: int = 3, seed: int = 0, goal: torch.Tensor | None = None,
                     skeleton: tuple[str, ...] | None = None) -> PlanningProblem:
    """The analytic problem (see the module docstring); ``goal`` overrides the goal set ``(G, 5)``;
    ``skeleton`` fixes the skill sequence (its length sets the horizon)."""
    obs = torch.tensor([[1.0, 0.0, 0.7, 0.05, 0.5]])
    if goal is None:
        goal = torch.tensor([[0.6, 0.0, 0.75, 0.05, 0.5], [0.4, 1.0, 0.25, 0.05, 0.5]])
    if skeleton is not None:
        horizon = len(skeleton)
    return PlanningProblem(obs, goal, analytic_skills(), AnalyticEncoder(), AnalyticCost(), horizon=horizon, seed=seed,
                           skeleton=skeleton)


@dataclass
class ReferencePlannerConfig(LatentPlannerConfig):
    num_samples: int = 256
    iterations: int = 40
    elite_fraction: float = 0.1


class ReferencePlanner(Planner):
    """Brute force over skeletons and attention structures, cross-entropy method over sub-goal latents."""

    name = "reference"

    def plan(self, problem: PlanningProblem) -> Plan:
        cfg = self.config or ReferencePlannerConfig()
        gen = torch.Generator().manual_seed(problem.seed)
        start = time.perf_counter()
        best: tuple[float, Any] | None = None
        for skeleton in problem.skeletons():
            for attention in attention_structures(problem, skeleton):
                score, subgoals = self._cem(problem, skeleton, attention, cfg, gen)
                if best is None or score > best[0]:
                    best = (score, (skeleton, attention, subgoals))
        assert best is not None
        skeleton, attention, subgoals = best[1]
        return build_plan(
            problem, skeleton, attention, subgoals, planner=self.name, cost_weight=cfg.cost_weight,
            timings={"search": time.perf_counter() - start},
        )

    @staticmethod
    def _cem(problem: PlanningProblem, skeleton, attention, cfg: ReferencePlannerConfig, gen: torch.Generator):
        counts = [problem.skill_map[n].n_out for n in skeleton]
        total, dim = sum(counts), problem.encoder.latent_dim
        mean = problem.encoder.sample_prior(total, gen)
        std = torch.full_like(mean, 0.3)
        n_elite = max(2, int(cfg.num_samples * cfg.elite_fraction))
        best_score, best = -1.0, mean
        for _ in range(cfg.iterations):
            samples = problem.encoder.clamp(mean + std * torch.randn(cfg.num_samples, total, dim, generator=gen))
            parts = list(torch.split(samples, counts, dim=1))
            with torch.no_grad():
                r = rollout(problem, skeleton, attention, parts)
                score = plan_score(r.feasibility, r.cost, cost_weight=cfg.cost_weight)
                # Elites are ranked by the unfloored log-objective: the floor makes the score flat far from
                # feasible plans, while sum(log f) - lambda * C still says which samples are closer.
                ranking = log_objective(r.feasibility.clamp(min=1e-30).log(), r.cost, cost_weight=cfg.cost_weight)
            top = ranking.topk(n_elite).indices
            if float(score[top[0]]) > best_score:
                best_score, best = float(score[top[0]]), samples[top[0]]
            mean, std = samples[top].mean(0), samples[top].std(0) + 1e-4
        return best_score, list(torch.split(best, counts, dim=0))


class AnalyticPlugin:
    """In-process plugin registering the analytic skills and their tools, encoder, cost and the reference planner."""

    @hookimpl
    def pasta_register_tools(self, register):
        for cls in (SplitSkill, MoveSkill, FlattenSkill):  # the tools exist only as names: nothing is simulated
            register(spec=ToolSpec(cls.spec.tool, description=f"analytic test tool of '{cls.spec.name}'"))

    @hookimpl
    def pasta_register_skills(self, register):
        for cls in (SplitSkill, MoveSkill, FlattenSkill):
            register(spec=cls.spec, factory=f"{__name__}:{cls.__name__}")

    @hookimpl
    def pasta_register_planners(self, register):
        register(name="reference", factory=f"{__name__}:ReferencePlanner", config=ReferencePlannerConfig,
                 summary="brute-force reference planner for the analytic test problem")

    @hookimpl
    def pasta_register_encoders(self, register):
        register(name="analytic", factory=f"{__name__}:AnalyticEncoder", summary="closed-form encoder for tests")

    @hookimpl
    def pasta_register_cost_models(self, register):
        register(name="analytic", factory=f"{__name__}:AnalyticCost", summary="closed-form cost for tests")

