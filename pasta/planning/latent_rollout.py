"""Roll a skill sequence forward in latent space and package the result as a :class:`~pasta.core.Plan`.

Used by planners to report their best candidate and by the conformance checker to re-evaluate a plan
with the problem's own models.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

from pasta.core import Plan, PlanningProblem, PlanStep, kept_indices
from pasta.core.errors import InputError
from pasta.core.plan import as_latents
from pasta.planning.batch import clamp_to_skill
from pasta.planning.clearance import Clearance
from pasta.planning.objective import FLOOR, plan_score


@dataclass
class Rollout:
    """Result of :func:`rollout` for ``B`` candidates sharing one skeleton and attention.

    Attributes:
        feasibility: ``(B, H)`` per-step feasibility.
        states: ``H`` tensors ``(B, K_h, D)``, the latent set after each step.
        cost: ``(B,)`` set cost of the last state against the goal.
        penalty: ``(B,)`` clearance penalty (:mod:`pasta.planning.clearance`; zeros when not asked for).
    """

    feasibility: torch.Tensor
    states: list[torch.Tensor]
    cost: torch.Tensor
    penalty: torch.Tensor | None = None


def rollout(
    problem: PlanningProblem,
    skeleton: Sequence[str],
    attention: Sequence[Sequence[int]],
    subgoals: Sequence[torch.Tensor],
    clearance: Clearance | None = None,
) -> Rollout:
    """Apply ``skeleton`` to the observed set.

    Args:
        problem: the planning problem (models and sets).
        skeleton: ``H`` skill names.
        attention: per step, the indices of the consumed entities in the set before the step.
        subgoals: per step, ``(B, M_h, D)`` latents of the produced entities.
        clearance: also score pieces moved through others.
    """
    if not (len(skeleton) == len(attention) == len(subgoals)):
        raise InputError(f"skeleton, attention and subgoals must have one entry per step, got {len(skeleton)}, {len(attention)}, {len(subgoals)}")
    skills = problem.skill_map
    batch = subgoals[0].shape[0] if subgoals else 1
    state = problem.obs.unsqueeze(0).expand(batch, -1, -1)
    feas, states = [], []
    penalty = state.new_zeros(batch)
    ext = clearance.start_extent.to(state.dtype).unsqueeze(0).expand(batch, -1, -1) if clearance is not None else None
    origin: list[int | None] = list(range(state.shape[1]))  # which observed entity each position still is
    for name, inputs, new in zip(skeleton, attention, subgoals):
        inputs, kept = list(inputs), list(kept_indices(state.shape[1], inputs))
        produced: list[int | None] = [None] * new.shape[1]  # new entities are no observed one
        origin = produced + [origin[i] for i in kept]
        feas.append(skills[name].feasibility(state[:, inputs], new))
        if clearance is not None:
            assert ext is not None  # set with clearance
            sweep = state.new_full((batch,), clearance.sweep.get(name, 0.0))
            p, ext = clearance.step_penalty(state[:, inputs], ext[:, inputs], new, state[:, kept], ext[:, kept], sweep)
            penalty = penalty + p
        state = torch.cat([new, state[:, kept]], 1)
        states.append(state)
    return Rollout(torch.stack(feas, -1), states, final_set_cost(problem, state, origin), penalty)


def final_set_cost(problem: PlanningProblem, state: torch.Tensor, origin: Sequence[int | None]) -> torch.Tensor:
    """``(B,)`` set cost of ``state (B, K, D)`` against the goal; ``origin[p]``: the observed entity at position
    ``p`` if it was never consumed. A fixed entity (``problem.fixed``) still there is matched to its own goal
    entity (:func:`pasta.planning.batch.fixed_matching`), as the shared search does."""
    at = {o: p for p, o in enumerate(origin) if o is not None}
    pairs = [(at[i], j) for i, j in problem.fixed if i in at]
    goal = problem.goal.unsqueeze(0).expand(state.shape[0], -1, -1)
    if not pairs:
        return problem.cost.set_cost(state, goal)
    from pasta.planning.batch import fixed_matching

    pos = torch.tensor([p for p, _ in pairs], dtype=torch.long).expand(state.shape[0], -1)
    rows, cols = fixed_matching(state, problem.goal, pos, [j for _, j in pairs], problem.cost)
    a = state.gather(1, rows[:, :, None].expand(-1, -1, state.shape[-1]))
    b = problem.goal[cols]
    d = a.shape[-1]
    return problem.cost.pairwise(a.reshape(-1, 1, d), b.reshape(-1, 1, d)).reshape(a.shape[0], a.shape[1]).sum(1)


def build_plan(
    problem: PlanningProblem,
    skeleton: Sequence[str],
    attention: Sequence[Sequence[int]],
    subgoals: Sequence[torch.Tensor],
    *,
    planner: str,
    cost_weight: float,
    floor: float = FLOOR,
    clearance_weight: float = 0.0,
    timings: dict[str, float] | None = None,
    info: dict | None = None,
) -> Plan:
    """Evaluate one candidate (``subgoals`` as ``(M_h, D)`` tensors) and return it as a :class:`Plan`.

    With ``clearance_weight > 0`` the score counts ``clearance_weight`` times the clearance penalty as
    cost (as the planners do) and ``plan.info["clearance_penalty"]`` records the penalty;
    ``plan.final_cost`` stays the set cost.
    """
    info = dict(info or {})
    with torch.no_grad():
        batched = [clamp_to_skill(s.detach(), problem.encoder, problem.skill_map[name]).unsqueeze(0)
                   for name, s in zip(skeleton, subgoals)]
        clearance = (Clearance.from_problem(problem.encoder, problem.obs, problem.goal, skills=problem.skills)
                     if clearance_weight > 0 else None)
        result = rollout(problem, skeleton, attention, batched, clearance)
        penalty = result.penalty
        assert penalty is not None  # rollout() always sets it
        score = plan_score(result.feasibility, result.cost + clearance_weight * penalty, cost_weight=cost_weight,
                           floor=floor)
        if clearance is not None:
            info["clearance_penalty"] = float(penalty[0])
    steps = tuple(
        PlanStep(
            skill=name,
            inputs=tuple(int(i) for i in inputs),
            subgoal=as_latents(new[0]),
            feasibility=float(result.feasibility[0, h]),
            state=as_latents(result.states[h][0]),
        )
        for h, (name, inputs, new) in enumerate(zip(skeleton, attention, batched))
    )
    return Plan(
        steps=steps,
        initial=as_latents(problem.obs),
        goal=as_latents(problem.goal),
        final_cost=float(result.cost[0]),
        score=float(score[0]),
        planner=planner,
        seed=problem.seed,
        timings=dict(timings or {}),
        info=info,
    )
