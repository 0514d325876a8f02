"""The beam planner: a cheap probe of every skill sequence, then the full search on the best few.

Written with the public helpers of :mod:`pasta.planning` only: :class:`~pasta.planning.LatentPlanner`
(sequence enumeration, seeding and packaging of the plan) and :func:`~pasta.planning.search` (the shared
batched latent optimiser, run once per probe and once on the kept sequences).
"""

from __future__ import annotations

import dataclasses
import time

from pasta.core import PlanningProblem
from pasta.planning import LatentPlanner, search
from pasta_pinch.plugin import BeamConfig


class BeamPlanner(LatentPlanner):
    """Probe each sequence with ``probe_samples`` samples x ``probe_iterations`` steps, keep the ``width``
    best-scoring sequences and search those with the full ``num_samples`` x ``iterations``."""

    name = "beam"
    method = "adam"
    config_class = BeamConfig

    def plan(self, problem: PlanningProblem):
        cfg = self.cfg
        t0 = time.perf_counter()
        sequences = self.sequences(problem)
        generator = self.generator(problem)
        probe = dataclasses.replace(cfg, num_samples=cfg.probe_samples, iterations=cfg.probe_iterations)
        probed = search(problem, sequences, probe, generator, method=self.method)
        ranked = sorted(probed.per_sequence, key=lambda s: -s["score"])
        kept = [tuple(s["skills"]) for s in ranked[: max(1, cfg.width)]]
        t1 = time.perf_counter()
        result = search(problem, kept, cfg, generator, method=self.method)
        info = self.info(sequences, [result])
        info["beam"] = [{"skills": list(s["skills"]), "probe_score": float(s["score"])} for s in ranked]
        return self.package(problem, result.skeleton, result.attention, result.subgoals,
                            timings={"probe": t1 - t0, **result.timings}, info=info)
