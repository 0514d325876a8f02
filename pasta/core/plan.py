"""Plans: a skill sequence with attention and sub-goal latents per step, serialisable to JSON.

Set bookkeeping convention (shared by planners, executor and checker): a step consumes the entities at
``inputs`` of the current set and the next set is ``[produced..., untouched...]``: the ``M_k`` new
entities first, then the entities the skill did not touch in their previous order
(:func:`kept_indices`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from pasta.core.errors import InputError

Latents = tuple[tuple[float, ...], ...]
"""A JSON-friendly ``(K, D)`` latent set."""

FORMAT_VERSION = 1

#: slack on the ``[0, 1]`` ranges of scores and feasibilities, for float rounding in planners
RANGE_TOLERANCE = 1e-6


def kept_indices(num_entities: int, inputs: Sequence[int]) -> tuple[int, ...]:
    """Indices of the entities a step does not touch, in order, for a set of ``num_entities``."""
    consumed = set(inputs)
    if len(consumed) != len(inputs) or any(not 0 <= i < num_entities for i in inputs):
        raise InputError(f"attention {tuple(inputs)} must be distinct indices into a set of {num_entities} entities")
    return tuple(i for i in range(num_entities) if i not in consumed)


def as_latents(array: Any) -> Latents:
    """Convert a ``(K, D)`` tensor, array or nested sequence to nested tuples of Python floats."""
    if hasattr(array, "detach"):
        array = array.detach().cpu().tolist()
    elif hasattr(array, "tolist"):
        array = array.tolist()
    return tuple(tuple(float(v) for v in row) for row in array)


@dataclass(frozen=True)
class PlanStep:
    """One planned skill application.

    Attributes:
        skill: skill name.
        inputs: attention, indices (into the set before this step) of the ``N_k`` consumed entities.
        subgoal: ``(M_k, D)`` latents of the produced entities.
        feasibility: predicted feasibility of this step, in ``[0, 1]``.
        state: ``(K_{h+1}, D)`` the whole latent set after the step (``subgoal`` rows first).
    """

    skill: str
    inputs: tuple[int, ...]
    subgoal: Latents
    feasibility: float
    state: Latents

    def to_dict(self) -> dict[str, Any]:
        return {
            "skill": self.skill,
            "inputs": list(self.inputs),
            "subgoal": [list(r) for r in self.subgoal],
            "feasibility": self.feasibility,
            "state": [list(r) for r in self.state],
        }

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PlanStep:
        return cls(
            skill=str(d["skill"]),
            inputs=tuple(int(i) for i in d["inputs"]),
            subgoal=as_latents(d["subgoal"]),
            feasibility=float(d["feasibility"]),
            state=as_latents(d["state"]),
        )


@dataclass(frozen=True)
class Plan:
    """A planner's answer.

    Attributes:
        steps: the planned steps in execution order.
        initial: ``(K_0, D)`` observed latent set the plan starts from.
        goal: ``(G, D)`` goal latent set.
        final_cost: predicted set cost between the last state and the goal.
        score: the planner objective ``prod_h max(f_h, 0.01) * exp(-lambda * cost)``.
        planner: planner name; ``seed``: the seed it ran with.
        timings: wall-clock seconds per phase (not part of the plan's identity, see :meth:`to_json`).
        info: JSON-safe extras (samples evaluated, sequences considered, ...).
    """

    steps: tuple[PlanStep, ...]
    initial: Latents
    goal: Latents
    final_cost: float
    score: float
    planner: str
    seed: int
    timings: dict[str, float] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def skills(self) -> tuple[str, ...]:
        return tuple(s.skill for s in self.steps)

    @property
    def horizon(self) -> int:
        return len(self.steps)

    def to_dict(self, *, timings: bool = True) -> dict[str, Any]:
        d: dict[str, Any] = {
            "format_version": FORMAT_VERSION,
            "planner": self.planner,
            "seed": self.seed,
            "skills": list(self.skills),
            "score": self.score,
            "final_cost": self.final_cost,
            "initial": [list(r) for r in self.initial],
            "goal": [list(r) for r in self.goal],
            "steps": [s.to_dict() for s in self.steps],
            "info": self.info,
        }
        if timings:
            d["timings"] = dict(self.timings)
        return d

    def problems(self) -> list[str]:
        """What is wrong with this plan's numbers, one phrase each (empty when it is valid).

        Valid: ``score`` and every step's ``feasibility`` finite and in ``[0, 1]``, ``final_cost`` finite
        and ``>= 0``, and every latent (``initial``, ``goal``, each step's ``subgoal`` and ``state``) finite.
        """
        out = []
        for name, value, low, high in [("score", self.score, 0.0, 1.0), ("final_cost", self.final_cost, 0.0, math.inf)]:
            out += _range_problem(name, value, low, high)
        out += _latent_problems("initial", self.initial) + _latent_problems("goal", self.goal)
        for h, s in enumerate(self.steps):
            where = f"step {h + 1} ({s.skill})"
            out += _range_problem(f"{where} feasibility", s.feasibility, 0.0, 1.0)
            out += _latent_problems(f"{where} subgoal", s.subgoal) + _latent_problems(f"{where} state", s.state)
        return out

    def check(self) -> Plan:
        """Return the plan if :meth:`problems` finds nothing, else raise :class:`InputError` naming every problem."""
        found = self.problems()
        if found:
            raise InputError(f"plan by {self.planner!r} is not valid: " + "; ".join(found))
        return self

    def to_json(self, *, timings: bool = True, indent: int | None = 2) -> str:
        """Serialise to strict JSON (no NaN/Infinity literals). ``timings=False`` drops wall-clock figures,
        so equal plans give equal bytes.

        Raises:
            InputError: the plan is not valid (:meth:`check`), or ``info`` holds a non-finite number or a
                value JSON cannot represent.
        """
        self.check()
        try:
            return json.dumps(self.to_dict(timings=timings), indent=indent, sort_keys=True, allow_nan=False)
        except (TypeError, ValueError) as exc:
            raise InputError(f"plan by {self.planner!r} cannot be written as strict JSON: {exc}") from None

    @classmethod
    def from_json(cls, text: str) -> Plan:
        """Parse and :meth:`check` a plan written by :meth:`to_json`.

        Raises:
            InputError: not strict JSON (e.g. a ``NaN`` literal), another format version, a missing or
                malformed field, or invalid values.
        """
        try:
            d = json.loads(text, parse_constant=_reject_constant)
        except json.JSONDecodeError as exc:
            raise InputError(f"plan file is not valid JSON: {exc}") from None
        if not isinstance(d, dict) or d.get("format_version") != FORMAT_VERSION:
            version = d.get("format_version") if isinstance(d, dict) else None
            raise InputError(f"plan format_version {version!r} is not {FORMAT_VERSION}")
        try:
            plan = cls(
                steps=tuple(PlanStep.from_dict(s) for s in d["steps"]),
                initial=as_latents(d["initial"]),
                goal=as_latents(d["goal"]),
                final_cost=float(d["final_cost"]),
                score=float(d["score"]),
                planner=str(d["planner"]),
                seed=int(d["seed"]),
                timings={k: float(v) for k, v in d.get("timings", {}).items()},
                info=dict(d.get("info", {})),
            )
        except KeyError as exc:
            raise InputError(f"plan file lacks the field {exc}") from None
        except (TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"plan file has a malformed field: {exc}") from None
        return plan.check()

    def summary(self) -> str:
        """Human-readable multi-line description."""
        lines = [f"plan by {self.planner} (seed {self.seed}): score {self.score:.4f}, final cost {self.final_cost:.5f}"]
        for h, s in enumerate(self.steps):
            lines.append(f"  {h + 1}. {s.skill:<10} on entities {list(s.inputs)} -> {len(s.subgoal)} new, f = {s.feasibility:.3f}")
        if self.timings:
            lines.append("  time: " + ", ".join(f"{k} {v:.2f}s" for k, v in self.timings.items()))
        return "\n".join(lines)


def _range_problem(name: str, value: float, low: float, high: float) -> list[str]:
    if not math.isfinite(value):
        return [f"{name} is {value}"]
    if not low - RANGE_TOLERANCE <= value <= high + RANGE_TOLERANCE:
        bounds = f"[{low:g}, {high:g}]" if math.isfinite(high) else f">= {low:g}"
        return [f"{name} {value:g} is outside {bounds}"]
    return []


def _latent_problems(name: str, latents: Latents) -> list[str]:
    bad = sum(1 for row in latents if not all(math.isfinite(v) for v in row))
    return [f"{name} has {bad} of {len(latents)} latents with NaN or infinite values"] if bad else []


def _reject_constant(name: str) -> float:
    raise InputError(f"plan file is not strict JSON: it contains {name}")
