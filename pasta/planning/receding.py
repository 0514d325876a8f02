"""Receding-horizon search over given skill sequences: optimise a window, commit its first step, slide.

Shared by the ``receding_horizon`` planner (over the given skeleton or every enumerated sequence) and
``prefix_beam``'s ``finish=receding`` (over the complete sequences its beam kept). Shapes: ``K`` entities,
``M_h`` entities produced by step ``h``, ``D`` latent dimension.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import torch

from pasta.core import PlanningProblem, kept_indices
from pasta.planning.config import LatentPlannerConfig
from pasta.planning.optimizer import SearchResult, search


@dataclass
class RecedingResult:
    """The committed steps (ready for :func:`pasta.planning.build_plan`) and one search per step."""

    skeleton: tuple[str, ...]
    attention: list[tuple[int, ...]]
    subgoals: list[torch.Tensor]  # per step (M_h, D)
    results: list[SearchResult]
    timings: dict[str, float] = field(default_factory=dict)

    def stages(self) -> list[dict]:
        """Per committed step: how many windows were searched, the skill committed and the window's score."""
        return [{"windows": len(r.per_sequence), "committed": self.skeleton[i], "score": r.score}
                for i, r in enumerate(self.results)]


def receding_search(problem: PlanningProblem, sequences: Sequence[Sequence[str]], config: LatentPlannerConfig,
                    generator: torch.Generator, *, window: int, method: str = "adam") -> RecedingResult:
    """For ``h = 0 ..``: search every window ``s[h : h + window]`` of the sequences that start with the
    committed steps, from the committed set (the observed ``(K, D)`` first), and commit the first step of
    the best window; stop when the committed steps are a complete sequence and the best window ended
    there (or no longer sequence continues them).

    A window that ends before its sequence does is scored against the goal with the same set cost,
    matching ``min(K, G)`` pairs (every entity of the smaller set gets a distinct partner in the larger one).
    Sequences may have different lengths; the committed steps always form a prefix of one of them.

    Raises:
        ValueError: ``window < 1`` or no sequence.
    """
    if int(window) < 1:
        raise ValueError(f"window must be >= 1, got {window}")
    full = [tuple(s) for s in sequences]
    if not full:
        raise ValueError("receding_search needs at least one skill sequence")
    skills: list[str] = []
    attention: list[tuple[int, ...]] = []
    subgoals: list[torch.Tensor] = []
    results: list[SearchResult] = []
    timings = {"sample": 0.0, "optimise": 0.0}
    state = problem.obs
    fixed = list(problem.fixed)  # (row in the committed set, goal index): where the fixed entities are now
    while True:
        h = len(skills)
        windows = list(dict.fromkeys(s[h : h + int(window)] for s in full if len(s) > h and s[:h] == tuple(skills)))
        if not windows:
            break
        result = search(problem, windows, config, generator, method=method, start=state, fixed=fixed)
        for key in timings:
            timings[key] += result.timings[key]
        results.append(result)
        skills.append(result.skeleton[0])
        attention.append(result.attention[0])
        subgoals.append(result.subgoals[0])
        kept = list(kept_indices(len(state), result.attention[0]))
        m = result.subgoals[0].shape[0]
        fixed = [(m + kept.index(i), j) for i, j in result.fixed]  # a search without them drops them
        state = torch.cat([result.subgoals[0], state[kept]], 0)
        if tuple(skills) in full and (len(result.skeleton) == 1 or not any(
                len(s) > len(skills) and s[: len(skills)] == tuple(skills) for s in full)):
            break  # complete: the best window ended here, or no longer sequence continues it
    return RecedingResult(tuple(skills), attention, subgoals, results, timings)
