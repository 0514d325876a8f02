"""The Task contract: a seeded generator of (initial state, goal) pairs with a ground-truth skill chain.

A task plugin registers a :class:`Task` subclass through ``pasta_register_tasks``. The machinery
(``pasta run``, ``pasta eval``, the oracle, :class:`pasta.testing.TaskContract`) only uses what
this interface names; how instances are generated (the built-in tasks run scripted experts in the
simulator, :class:`pasta.tasks.base.Task`) is the plugin's business.

An *instance* (what :meth:`Task.instance` returns) must provide:

- ``seed``: the generator seed it was made from;
- ``init``: the simulator state to start from (``Simulator.set_state``);
- ``init_points``: ``(P, 3)`` float32, the observed initial dough;
- ``goal``: ``(P, 3)`` float32, the observed goal dough (same particles, so ``P`` matches);
- ``skeleton``: ``list[str]``, the skills of the chain that produced the goal (``Task.skeleton``).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar

from pasta.core.scene import Scene

if TYPE_CHECKING:
    import numpy as np


@dataclass
class TaskScore:
    """A final dough scored against an instance's goal.

    Attributes:
        emd_initial: EMD between the initial dough and the goal.
        emd_final: EMD between the final dough and the goal.
        improvement: normalised improvement ``(emd_initial - emd_final) / emd_initial`` (1 = the goal).
        success: ``improvement > Task.threshold``.
    """

    emd_initial: float
    emd_final: float
    improvement: float
    success: bool


class Task(ABC):
    """Base class of every task plugin.

    Subclasses set :attr:`name` (the registry name), :attr:`skeleton` (the ground-truth skill chain, whose
    skills must be registered) and implement :meth:`generate`, :meth:`instance`, :meth:`score`,
    :meth:`make_sim` and :attr:`threshold`.
    """

    name: ClassVar[str] = ""
    #: skills of the ground-truth chain, in order (``("cut", "push", "roll")``)
    skeleton: ClassVar[tuple[str, ...]] = ()
    summary: ClassVar[str] = ""
    #: run settings this task asks for, ``{key: value}`` in ``pasta config`` terms, under the command line's
    #: (e.g. ``{"planner": "receding_horizon", "skeleton": "task"}``: plan with that planner and the task's
    #: own skill chain given, as the paper did for CRS-Twice)
    run_defaults: ClassVar[Mapping[str, Any]] = {}
    #: static tools (registry names) every instance of this task stands up, e.g. ``("board",)``: the scene the
    #: planner fits the skills to (a skill that needs a tool the scene lacks is never planned)
    static_tools: ClassVar[tuple[str, ...]] = ()

    def scene(self) -> Scene:
        """The scene of this task's instances (:class:`~pasta.core.Scene`); surface heights are filled in
        from the floor and the standing tools (:func:`pasta.tasks.scene.resolve_scene`). Override to name
        surfaces that are not tools, or to restrict the movable tools at hand."""
        return Scene(static=tuple(self.static_tools), source=f"task {self.name}")

    @property
    def horizon(self) -> int:
        """Steps of the ground-truth chain, ``len(skeleton)``; the default planning horizon."""
        return len(self.skeleton)

    @property
    @abstractmethod
    def threshold(self) -> float:
        """Success when the normalised improvement exceeds this (strictly)."""

    @abstractmethod
    def generate(self, seed: int, sim: Any = None) -> Any:
        """Generate the instance of ``seed`` (no cache); the same seed must give the same instance."""

    @abstractmethod
    def instance(self, seed: int, *, sim: Any = None, cache: bool = True) -> Any:
        """The instance of ``seed`` (see the module docstring), from a cache when the task keeps one."""

    @abstractmethod
    def score(self, final_points: np.ndarray, instance: Any) -> TaskScore:
        """Score the observed final dough ``(P, 3)`` against ``instance``'s goal ``(P, 3)``."""

    @abstractmethod
    def make_sim(self) -> Any:
        """A simulator that ``instance.init`` loads into (``sim.set_state(instance.init)``)."""
