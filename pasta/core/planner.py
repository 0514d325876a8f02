"""The Planner contract and the planning problem it solves."""

from __future__ import annotations

import itertools
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from pasta.core.errors import CardinalityError, InputError
from pasta.core.shapes import check_latents
from pasta.core.skill import Skill, SkillSpec

if TYPE_CHECKING:
    import torch

    from pasta.core.cost import CostModel
    from pasta.core.encoder import Encoder
    from pasta.core.plan import Plan


@dataclass
class PlanningProblem:
    """Everything a planner needs; planners receive their models, they never build them.

    Attributes:
        obs: ``(K_0, D)`` latents of the observed entities.
        goal: ``(G, D)`` latents of the goal entities.
        skills: the skills the plan may use (their order fixes the enumeration order).
        encoder: gives prior samples and the centroid box for new sub-goal entities.
        cost: the set cost between the final state and the goal.
        horizon: number of skill steps ``H``.
        seed: random seed; the same seed must give the same plan.
        skeleton: optional fixed skill sequence (names) of length ``H``.
        candidates: optional skill sequences to search instead of every sequence of length ``H`` (a warm
            start: a closed loop re-plans from the remaining steps of its plan and their one-step
            extensions); they may differ in length, and those that cannot reach the goal's entity count are
            dropped. At most one of ``skeleton`` and ``candidates``.
        fixed: pairs ``(i, j)``: observed entity ``i`` already is goal entity ``j``, unchanged (e.g.
            :func:`pasta.core.matching.unchanged_pairs` on the two clouds' entities). The shared search
            never attends such an entity and matches it to its goal entity in the set cost; each index
            appears at most once. Empty: no entity is known to be in place.
    """

    obs: torch.Tensor
    goal: torch.Tensor
    skills: Sequence[Skill]
    encoder: Encoder
    cost: CostModel
    horizon: int
    seed: int = 0
    skeleton: tuple[str, ...] | None = None
    fixed: tuple[tuple[int, int], ...] = ()
    candidates: tuple[tuple[str, ...], ...] = ()

    def __post_init__(self) -> None:
        dim = self.encoder.latent_dim
        check_latents(self.obs, "observed latents", dim=dim)
        check_latents(self.goal, "goal latents", dim=dim)
        if len(self.obs) == 0 or len(self.goal) == 0:
            raise InputError(f"need at least one observed and one goal entity, got {len(self.obs)} and {len(self.goal)}")
        if not isinstance(self.horizon, int) or self.horizon < 1:
            raise InputError(f"horizon must be an integer >= 1, got {self.horizon!r}")
        self.fixed = tuple(sorted((int(i), int(j)) for i, j in self.fixed))
        rows, cols = [i for i, _ in self.fixed], [j for _, j in self.fixed]
        if (len(set(rows)) != len(rows) or len(set(cols)) != len(cols)
                or any(not 0 <= i < len(self.obs) for i in rows) or any(not 0 <= j < len(self.goal) for j in cols)):
            raise InputError(f"fixed must pair distinct observed entities (0..{len(self.obs) - 1}) with distinct goal "
                             f"entities (0..{len(self.goal) - 1}), got {list(self.fixed)}")
        names = [s.name for s in self.skills]
        if not names or len(set(names)) != len(names):
            raise InputError(f"skills must be a non-empty list of distinct skills, got {names}")
        if self.skeleton is not None:
            self.skeleton = tuple(self.skeleton)
            unknown = [n for n in self.skeleton if n not in names]
            if unknown:
                raise InputError(f"skeleton uses unknown skills {unknown}; the problem's skills are {names}")
            if len(self.skeleton) != self.horizon:
                raise InputError(f"skeleton has {len(self.skeleton)} steps but the horizon is {self.horizon}")
        self.candidates = tuple(tuple(str(n) for n in seq) for seq in self.candidates)
        if self.candidates:
            if self.skeleton is not None:
                raise InputError("give a skeleton or candidate sequences, not both")
            unknown = sorted({n for seq in self.candidates for n in seq} - set(names))
            if unknown or not all(self.candidates):
                raise InputError(f"candidate sequences must be non-empty and use the problem's skills {names}; "
                                 f"unknown: {unknown}")

    @property
    def sequences_given(self) -> bool:
        """The caller chose the sequences (a skeleton or candidates): planners search those, no others."""
        return self.skeleton is not None or bool(self.candidates)

    @property
    def skill_map(self) -> dict[str, Skill]:
        return {s.name: s for s in self.skills}

    def skeletons(self) -> list[tuple[str, ...]]:
        """The skill sequences to search: the given skeleton, the candidates that reach the goal's entity
        count, or every feasible one (see :func:`enumerate_skeletons`)."""
        specs = [s.spec for s in self.skills]
        if self.candidates:
            by_name = {s.name: s for s in specs}
            kept = [seq for seq in dict.fromkeys(self.candidates)
                    if _reachable([by_name[n] for n in seq], len(self.obs), len(self.goal))]
            if not kept:
                raise CardinalityError(f"none of the {len(self.candidates)} candidate sequences turns {len(self.obs)} "
                                       f"observed entities into {len(self.goal)} goal entities; "
                                       + _cardinalities(specs))
            return kept
        if self.skeleton is not None:
            check_skeleton(self.skeleton, specs, len(self.obs), len(self.goal))
            return [self.skeleton]
        return enumerate_skeletons(specs, self.horizon, len(self.obs), len(self.goal))


def enumerate_skeletons(specs: Sequence[SkillSpec], horizon: int, k_obs: int, k_goal: int) -> list[tuple[str, ...]]:
    """Every skill sequence of length ``horizon`` that turns ``k_obs`` entities into ``k_goal``.

    A sequence is kept when ``sum(M_k - N_k) == k_goal - k_obs``, every step has enough entities to consume and
    the count moves only toward ``k_goal`` without passing it (:func:`toward_goal`). Order: lexicographic in the
    order of ``specs``.

    Raises:
        CardinalityError: no sequence qualifies; the message names both counts and the cardinalities.
    """
    out = []
    for seq in itertools.product(specs, repeat=horizon):
        if _reachable(seq, k_obs, k_goal):
            out.append(tuple(s.name for s in seq))
    if not out:
        raise CardinalityError(_cardinality_message(specs, horizon, k_obs, k_goal))
    return out


def check_skeleton(skeleton: Sequence[str], specs: Sequence[SkillSpec], k_obs: int, k_goal: int) -> None:
    """Raise :class:`CardinalityError` if ``skeleton`` cannot turn ``k_obs`` entities into ``k_goal``."""
    by_name = {s.name: s for s in specs}
    if not _reachable([by_name[n] for n in skeleton], k_obs, k_goal, monotone=False):
        raise CardinalityError(
            f"skeleton {list(skeleton)} cannot turn {k_obs} observed entities into {k_goal} goal entities; "
            + _cardinalities(specs)
        )


def toward_goal(k: int, delta: int, k_goal: int) -> bool:
    """A step changing the entity count ``k`` by ``delta`` moves it toward ``k_goal`` without passing it (or keeps
    it). The searched sequences never cut a piece only to join it again, nor join pieces only to cut them apart,
    so a skill that joins pieces widens no search of a task whose count only grows."""
    return delta == 0 or (delta > 0 and k + delta <= k_goal) or (delta < 0 and k + delta >= k_goal)


def _reachable(seq: Sequence[SkillSpec], k_obs: int, k_goal: int, monotone: bool = True) -> bool:
    """``seq`` turns ``k_obs`` entities into ``k_goal`` and every step has the entities it consumes; with
    ``monotone`` (searched sequences, not a skeleton the user gave) every step moves the count toward the goal's
    (:func:`toward_goal`)."""
    k = k_obs
    for s in seq:
        if k < s.n_in or (monotone and not toward_goal(k, s.delta, k_goal)):
            return False
        k += s.delta
    return k == k_goal


def _cardinalities(specs: Sequence[SkillSpec]) -> str:
    return "skill cardinalities (N_k -> M_k): " + ", ".join(f"{s.name} {s.n_in}->{s.n_out}" for s in specs)


def _cardinality_message(specs: Sequence[SkillSpec], horizon: int, k_obs: int, k_goal: int) -> str:
    detour = ""
    if any(_reachable(seq, k_obs, k_goal, monotone=False) for seq in itertools.product(specs, repeat=horizon)):
        detour = (" (only by a detour: the searched sequences move the count toward the goal's, never away or past "
                  "it; give the skeleton to plan one)")
    return (
        f"no sequence of {horizon} skills turns {k_obs} observed entities into {k_goal} goal entities{detour}; "
        f"{_cardinalities(specs)}. Try another horizon or a skill with the missing cardinality."
    )


class Planner(ABC):
    """Base class of planner plugins. ``config`` is the planner's dataclass config (or ``None`` for defaults)."""

    name: ClassVar[str]

    def __init__(self, config: Any = None) -> None:
        self.config = config

    @abstractmethod
    def plan(self, problem: PlanningProblem) -> Plan:
        """Search skill sequences, attention and sub-goals; return the best :class:`~pasta.core.plan.Plan`."""
