"""The planning objective shared by every planner (PASTA, section 4.3 of the paper).

Plans are scored by ``prod_h max(f_h, FLOOR) * exp(-lambda * C)`` (:func:`plan_score`, the paper's score
with its 0.01 floor). The planners maximise its log, ``sum_h log f_h - lambda * C`` (:func:`log_objective`),
with ``log f_h`` from the feasibility logits: it has the score's maximiser, and a step whose feasibility
has saturated at 0 still gets a gradient of order 1. (The paper maximised the floored product plus
``0.01 * sum_h f_h``; its gradient for a step below the floor comes only from that sum and vanishes with
the sigmoid's slope: on crs it left the push step at ``f = 0``, docs/experiments.)
"""

from __future__ import annotations

import torch

#: the feasibility floor of the reported score (the paper's 0.01): one infeasible step does not zero a plan
FLOOR = 0.01


def plan_score(feasibility: torch.Tensor, cost: torch.Tensor, *, cost_weight: float, floor: float = FLOOR) -> torch.Tensor:
    """Score of candidate plans: ``prod_h max(f_h, floor) * exp(-cost_weight * cost)``.

    Args:
        feasibility: ``(B, H)`` per-step feasibility in ``[0, 1]``.
        cost: ``(B,)`` predicted set cost between the final state and the goal (>= 0).

    Returns:
        ``(B,)`` scores in ``[0, 1]``; higher is better.
    """
    return feasibility.clamp(min=floor).prod(-1) * torch.exp(-cost_weight * cost.clamp(min=0.0))


def log_objective(log_feasibility: torch.Tensor, cost: torch.Tensor, *, cost_weight: float) -> torch.Tensor:
    """``sum_h log f_h - cost_weight * cost`` -> ``(B,)``: the log of the unfloored :func:`plan_score`.

    Args:
        log_feasibility: ``(B, H)`` per-step log feasibility (<= 0).
        cost: ``(B,)`` predicted set cost (>= 0).
    """
    return log_feasibility.sum(-1) - cost_weight * cost.clamp(min=0.0)
