"""The planning objective shared by every planner (PASTA, section 4.3 of the paper)."""

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
