"""Planning machinery shared by the planner plugins: the public helpers a planner is written with.

Everything below is importable from ``pasta.planning`` (loaded on first use, so importing the package, or
a planner's config module, does not import torch). Shapes: ``B`` candidates, ``H`` steps, ``K`` entities,
``G`` goal entities, ``M_h`` entities produced by step ``h``, ``D`` latent dimension.

Building blocks (any planner):

- :func:`attention_structures` ``(problem, skeleton) -> [[(i, ...) per step], ...]``: every choice of
  consumed entities per step (small problems; the built-in planners sample them).
- :func:`rollout` ``(problem, skeleton, attention, subgoals [(B, M_h, D)]) -> Rollout``: per-step
  feasibility ``(B, H)``, the sets after each step ``[(B, K_h, D)]`` and the final set cost ``(B,)``.
- :func:`plan_score` ``(feasibility (B, H), cost (B,), cost_weight) -> (B,)``: the score
  ``prod_h max(f_h, FLOOR) * exp(-cost_weight * C)``; :func:`log_objective` its unfloored log, which the
  planners maximise and rank by.
- :func:`build_plan` ``(problem, skeleton, attention, subgoals [(M_h, D)], planner=, cost_weight=)
  -> Plan``: re-evaluate one candidate with the problem's models and package it (what a planner returns).

The batched latent optimiser (what the built-in planners use):

- :class:`LatentPlanner`: base class; override ``sequences(problem)`` and set ``method`` (``"adam"`` /
  ``"cem"``) and ``config_class`` (a :class:`LatentPlannerConfig` subclass).
- :func:`search` ``(problem, sequences, config, generator) -> SearchResult``: all samples of all
  sequences optimised in a few tensor ops per iteration.
- :func:`receding_search` ``(problem, sequences, config, generator, window=) -> RecedingResult``: optimise a
  window of steps, commit its first, slide (``receding_horizon``).
- :func:`sample_candidates`, :func:`evaluate`: the candidate batch and its evaluation (:mod:`pasta.planning.batch`).
"""

from __future__ import annotations

import importlib
from typing import Any

#: public name -> module that defines it
_EXPORTS = {
    "attention_structures": "pasta.planning.attention",
    "Rollout": "pasta.planning.latent_rollout",
    "rollout": "pasta.planning.latent_rollout",
    "build_plan": "pasta.planning.latent_rollout",
    "plan_score": "pasta.planning.objective",
    "log_objective": "pasta.planning.objective",
    "FLOOR": "pasta.planning.objective",
    "LatentPlanner": "pasta.planning.planner",
    "LatentPlannerConfig": "pasta.planning.config",
    "HalvingConfig": "pasta.planning.config",
    "search": "pasta.planning.optimizer",
    "SearchResult": "pasta.planning.optimizer",
    "receding_search": "pasta.planning.receding",
    "RecedingResult": "pasta.planning.receding",
    "sample_candidates": "pasta.planning.batch",
    "evaluate": "pasta.planning.batch",
    "CandidateBatch": "pasta.planning.batch",
    "Clearance": "pasta.planning.clearance",
}

__all__ = sorted(_EXPORTS)  # noqa: PLE0605 - the lazy names of _EXPORTS, one list to keep


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f"module 'pasta.planning' has no attribute '{name}'")
    value = getattr(importlib.import_module(_EXPORTS[name]), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
