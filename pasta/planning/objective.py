"""The planning objective shared by every planner (PASTA, section 4.3 of the paper).

Plans are scored by ``prod_h f_h * exp(-lambda * C)`` (:func:`plan_score`). Two differentiable
surrogates can be maximised (``planner.objective``):

- ``"log"`` (default): the log of the score, ``sum_h log f_h - lambda * C`` (:func:`log_objective`),
  with ``log f_h`` from the feasibility logits. It has the score's maximiser, and a step whose
  feasibility has saturated at 0 still gets a gradient of order 1.
- ``"product"``: the paper's floored product plus ``aux_weight * sum_h f_h`` (:func:`plan_objective`).
  Its gradient for a step with ``f_h`` below the floor comes only from the auxiliary sum and vanishes
  with the sigmoid's slope; on crs this left the push step at ``f = 0`` (docs/planning.md).
"""

from __future__ import annotations

import torch


def plan_score(feasibility: torch.Tensor, cost: torch.Tensor, *, cost_weight: float, floor: float) -> torch.Tensor:
    """Score of candidate plans: ``prod_h max(f_h, floor) * exp(-cost_weight * cost)``.

    Args:
        feasibility: ``(B, H)`` per-step feasibility in ``[0, 1]``.
        cost: ``(B,)`` predicted set cost between the final state and the goal (>= 0).

    Returns:
        ``(B,)`` scores in ``[0, 1]``; higher is better.
    """
    return feasibility.clamp(min=floor).prod(-1) * torch.exp(-cost_weight * cost.clamp(min=0.0))


def plan_loss(feasibility: torch.Tensor, cost: torch.Tensor, *, cost_weight: float, floor: float, aux_weight: float) -> torch.Tensor:
    """Per-sample loss to minimise: ``-score - aux_weight * sum_h f_h`` (the sum keeps gradients alive) -> ``(B,)``."""
    return -plan_score(feasibility, cost, cost_weight=cost_weight, floor=floor) - aux_weight * feasibility.sum(-1)


def plan_objective(feasibility: torch.Tensor, cost: torch.Tensor, *, cost_weight: float, floor: float, aux_weight: float) -> torch.Tensor:
    """The quantity the planners maximise, ``score + aux_weight * sum_h f_h`` -> ``(B,)`` (``= -plan_loss``)."""
    return -plan_loss(feasibility, cost, cost_weight=cost_weight, floor=floor, aux_weight=aux_weight)


def log_objective(log_feasibility: torch.Tensor, cost: torch.Tensor, *, cost_weight: float) -> torch.Tensor:
    """``sum_h log f_h - cost_weight * cost`` -> ``(B,)``: the log of the unfloored :func:`plan_score`.

    Args:
        log_feasibility: ``(B, H)`` per-step log feasibility (<= 0).
        cost: ``(B,)`` predicted set cost (>= 0).
    """
    return log_feasibility.sum(-1) - cost_weight * cost.clamp(min=0.0)
