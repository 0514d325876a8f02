"""Base class of the latent planners: enumerate sequences, run the shared optimiser, package the plan."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import Any, ClassVar

import torch

from pasta.core import Plan, Planner, PlanningProblem
from pasta.planning.config import LatentPlannerConfig
from pasta.planning.optimizer import SearchResult, search
from pasta.planning.latent_rollout import build_plan


class LatentPlanner(Planner):
    """A planner that searches skill sequences with :func:`pasta.planning.optimizer.search`.

    Subclasses choose the sequences (:meth:`sequences`), the optimisation ``method`` and the config class.
    """

    method: ClassVar[str] = "adam"
    config_class: ClassVar[type[LatentPlannerConfig]] = LatentPlannerConfig

    @property
    def cfg(self) -> Any:
        return self.config if self.config is not None else self.config_class()

    def sequences(self, problem: PlanningProblem) -> list[tuple[str, ...]]:
        """Skill sequences to search (raises :class:`~pasta.core.CardinalityError` when there is none)."""
        return problem.skeletons()

    def search_options(self) -> dict[str, Any]:
        return {}

    def generator(self, problem: PlanningProblem) -> torch.Generator:
        return torch.Generator().manual_seed(int(problem.seed))

    def plan(self, problem: PlanningProblem) -> Plan:
        t0 = time.perf_counter()
        sequences = self.sequences(problem)
        t1 = time.perf_counter()
        result = search(problem, sequences, self.cfg, self.generator(problem), method=self.method, **self.search_options())
        return self.package(problem, result.skeleton, result.attention, result.subgoals,
                            timings={"enumerate": t1 - t0, **result.timings}, info=self.info(sequences, [result]))

    def info(self, sequences: Sequence[Sequence[str]], results: Sequence[SearchResult]) -> dict[str, Any]:
        info = {
            "method": self.method,
            "sequences": len(sequences),
            "samples": sum(r.samples for r in results),
            "evaluations": sum(r.evaluations for r in results),
            "iterations": int(self.cfg.iterations),
            "successive_halving": bool(getattr(self.cfg, "halving_points", ())) and self.method == "adam",
            "per_sequence": results[-1].per_sequence if len(results) == 1 else [r.per_sequence for r in results],
        }
        if results and results[0].fixed:  # observed entities kept out of the attention search (at their goal entity)
            info["fixed"] = [list(p) for p in results[0].fixed]
        return info

    def package(self, problem, skeleton, attention, subgoals, *, timings: dict[str, float], info: dict[str, Any]) -> Plan:
        """Re-evaluate the chosen candidate with :func:`build_plan`; time it as ``select``."""
        t0 = time.perf_counter()
        plan = build_plan(problem, skeleton, attention, subgoals, planner=self.name, cost_weight=self.cfg.cost_weight,
                          clearance_weight=float(self.cfg.clearance_weight), info=info)
        timings = {**timings, "select": time.perf_counter() - t0}
        timings["total"] = sum(timings.values())
        return dataclasses.replace(plan, timings=timings)
