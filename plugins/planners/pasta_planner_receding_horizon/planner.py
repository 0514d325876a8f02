"""The 'receding_horizon' planner: optimise a window of steps, commit the first, slide (long tasks)."""

from __future__ import annotations

import time

import torch

from pasta.core import Plan, PlanningProblem, kept_indices
from pasta.core.errors import ConfigError
from pasta.planning import LatentPlanner, search
from pasta_planner_receding_horizon.config import RecedingHorizonConfig


class RecedingHorizonPlanner(LatentPlanner):
    """Receding horizon in latent space (the paper's ``rhp`` mode for CRS-Twice).

    For ``h = 0 .. H-1``: optimise every window ``s[h : h + window]`` of the remaining feasible sequences
    (the given skeleton, or every enumerated sequence that starts with the committed steps), starting from
    the committed latent set; commit the first step of the best window (skill, attention, sub-goal) and
    slide. A window that ends before ``H`` is scored against the goal with the same set cost, matching
    ``min(K, G)`` pairs (every entity of the smaller set gets a distinct partner in the larger one).
    """

    name = "receding_horizon"
    method = "adam"
    config_class = RecedingHorizonConfig

    def plan(self, problem: PlanningProblem) -> Plan:
        cfg = self.cfg
        if int(cfg.window) < 1:
            raise ConfigError(f"planner.window must be >= 1, got {cfg.window}")
        t0 = time.perf_counter()
        full = problem.skeletons()
        timings = {"enumerate": time.perf_counter() - t0, "sample": 0.0, "optimise": 0.0}
        gen = self.generator(problem)
        skills: list[str] = []
        attention: list[tuple[int, ...]] = []
        subgoals: list[torch.Tensor] = []
        results = []
        state = problem.obs
        fixed = list(problem.fixed)  # (row in the committed set, goal index): where the fixed entities are now
        horizon = len(full[0])
        for h in range(horizon):
            w = min(int(cfg.window), horizon - h)
            windows = list(dict.fromkeys(s[h : h + w] for s in full if list(s[:h]) == skills))
            result = search(problem, windows, cfg, gen, method=self.method, start=state, fixed=fixed)
            for key in ("sample", "optimise"):
                timings[key] += result.timings[key]
            results.append(result)
            skills.append(result.skeleton[0])
            attention.append(result.attention[0])
            subgoals.append(result.subgoals[0])
            kept = list(kept_indices(len(state), result.attention[0]))
            m = result.subgoals[0].shape[0]
            fixed = [(m + kept.index(i), j) for i, j in result.fixed]  # a search without them drops them
            state = torch.cat([result.subgoals[0], state[kept]], 0)
        info = self.info(full, results)
        info["window"] = int(cfg.window)
        info["stages"] = [{"windows": len(r.per_sequence), "committed": skills[i], "score": r.score} for i, r in enumerate(results)]
        return self.package(problem, tuple(skills), attention, subgoals, timings=timings, info=info)
