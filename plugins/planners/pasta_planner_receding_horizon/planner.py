"""The 'receding_horizon' planner: optimise a window of steps, commit the first, slide (long tasks)."""

from __future__ import annotations

import time

from pasta.core import Plan, PlanningProblem
from pasta.core.errors import ConfigError
from pasta.planning import LatentPlanner, receding_search
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
        result = receding_search(problem, full, cfg, self.generator(problem), window=int(cfg.window), method=self.method)
        timings.update(result.timings)
        info = self.info(full, result.results)
        info["window"] = int(cfg.window)
        info["stages"] = result.stages()
        return self.package(problem, result.skeleton, result.attention, result.subgoals, timings=timings, info=info)
