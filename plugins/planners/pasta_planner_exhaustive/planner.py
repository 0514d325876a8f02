"""The 'exhaustive' planner: PASTA's search (every sequence, random attention, Adam on sub-goal latents)."""

from __future__ import annotations

from pasta.core import CardinalityError, PlanningProblem, enumerate_skeletons
from pasta.planning import LatentPlanner
from pasta_planner_exhaustive.config import ExhaustiveConfig


class ExhaustivePlanner(LatentPlanner):
    """Every skill sequence with the right cardinality, random attention, Adam on the sub-goal latents.

    With ``max_horizon = N > 0`` the sequences of every length ``1..N`` are optimised together and the
    best plan of any length wins (its horizon may then differ from ``problem.horizon``).
    """

    name = "exhaustive"
    method = "adam"
    config_class = ExhaustiveConfig

    def sequences(self, problem: PlanningProblem) -> list[tuple[str, ...]]:
        max_h = int(getattr(self.cfg, "max_horizon", 0) or 0)
        if max_h <= 0 or problem.sequences_given:
            return problem.skeletons()
        specs = [s.spec for s in problem.skills]
        out: list[tuple[str, ...]] = []
        for h in range(1, max_h + 1):
            try:
                out.extend(enumerate_skeletons(specs, h, len(problem.obs), len(problem.goal)))
            except CardinalityError:
                continue
        if not out:
            raise CardinalityError(
                f"no sequence of 1 to {max_h} skills turns {len(problem.obs)} observed entities into "
                f"{len(problem.goal)} goal entities; skill cardinalities (N_k -> M_k): "
                + ", ".join(f"{s.name} {s.n_in}->{s.n_out}" for s in specs)
            )
        return out
