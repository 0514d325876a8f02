"""The step-monitor contract: whether a skill step starts, when it ends and whether it is retried.

Every skill step, whoever drives it (a scripted expert, a heuristic controller, a learned policy), runs
through one loop (:func:`pasta.tasks.step.run_skill`) that asks one :class:`StepMonitor` three questions:

- before the step: :meth:`StepMonitor.should_run`, may the step start at all (a piece already at its goal
  is not worked on);
- after every env step: :meth:`StepMonitor.should_stop`, does the step end now, given what the controller
  said (:class:`Stop`) and where the piece is;
- after the step: :meth:`StepMonitor.should_retry`, did it visibly fail, so that it runs once more.

Every answer that ends or skips a step is a :class:`Stop` reason, which the executor prints and logs:
nothing is cut short or skipped silently.

A controller reports why it stops through :meth:`pasta.core.Controller.act`: ``None`` (go on), or a
:class:`Stop` (``DONE``: its skill is finished; ``CAP``: it used up its own action budget, the way a learned
policy's step cap ends it). ``True``/``False`` are read as ``DONE``/``None`` (:func:`stop_reason`), so a
controller that only knows "done" stays a two-line function.
"""

from __future__ import annotations

from collections.abc import Callable

from abc import ABC, abstractmethod
from enum import StrEnum
from typing import TYPE_CHECKING, Any

from pasta.core.errors import PluginValidationError

if TYPE_CHECKING:
    import numpy as np

__all__ = ["Stop", "StepMonitor", "stop_reason"]


class Stop(StrEnum):
    """Why a skill step ended, or why it never started."""

    #: the controller says its skill is finished
    DONE = "done"
    #: the controller used up its own action budget (a learned policy's step cap)
    CAP = "cap"
    #: the skill's step limit (``run_skill(max_steps=)``, the skill's ``max_steps``)
    LIMIT = "limit"
    #: the monitor: the piece, having come closer to its goal, moves away from it again
    REGRESSED = "regressed"
    #: the monitor skipped the step: its piece already is at the step's goal
    AT_GOAL = "at_goal"
    #: the simulation diverged during the step (the episode ends, scored as it is)
    DIVERGED = "diverged"

    @property
    def describe(self) -> str:
        """A few words for logs and the command line."""
        return _WORDS[self]


_WORDS = {
    Stop.DONE: "done",
    Stop.CAP: "at the controller's step cap",
    Stop.LIMIT: "at the skill's step limit",
    Stop.REGRESSED: "stopped: the piece moved away from its goal again",
    Stop.AT_GOAL: "skipped: the piece already is at its goal",
    Stop.DIVERGED: "the simulation diverged",
}


def stop_reason(said: Any) -> Stop | None:
    """What a controller's :meth:`~pasta.core.Controller.act` said, as a :class:`Stop` or ``None`` (go on).

    ``None`` and ``False`` go on, ``True`` is :attr:`Stop.DONE`, a :class:`Stop` (or its value) is itself;
    only :attr:`Stop.DONE` and :attr:`Stop.CAP` are a controller's to say.
    """
    if said is None or said is False:
        return None
    if said is True:
        return Stop.DONE
    try:
        reason = Stop(said)
    except ValueError:
        raise PluginValidationError(f"a controller's act() returned stop={said!r}; expected None, a bool, "
                                    f"'{Stop.DONE}' or '{Stop.CAP}'") from None
    if reason not in (Stop.DONE, Stop.CAP):
        raise PluginValidationError(f"a controller's act() returned stop={said!r}; a controller may only say "
                                    f"'{Stop.DONE}' or '{Stop.CAP}' (the monitor decides the others)")
    return reason


class StepMonitor(ABC):
    """Decides, for every controller, whether a step starts, when it ends and whether it is retried.

    One instance serves one step at a time: :meth:`begin` resets it. ``watch`` says whether the
    controller's own stop is trusted (``Controller.watch`` is ``False``: experts and heuristics run until
    they say so or hit the limit) or watched (learned policies, whose done head can stay low while they
    push a piece past its goal, or fire early).
    """

    @abstractmethod
    def should_run(self, piece: np.ndarray, goal: np.ndarray | None, *, keeps_count: bool,
                   watch: bool, at_goal: float | None = None) -> Stop | None:
        """``None``: run the step on ``piece (P, 3)`` towards ``goal (G, 3)``; a :class:`Stop`: skip it, and why.
        ``keeps_count``: the step makes as many pieces as it takes (a cut does not); ``at_goal``: the skill's
        own distance within which its piece is at its goal (:attr:`pasta.core.Skill.at_goal`; ``None``: the
        monitor's)."""

    @abstractmethod
    def begin(self, piece: np.ndarray, goal: np.ndarray | None, *, limit: int, watch: bool,
              unfinished: Callable[[np.ndarray], bool] | None = None) -> None:
        """Start watching a step of at most ``limit`` env steps on ``piece (P, 3)`` towards ``goal``;
        ``unfinished(piece)``: the skill's own measure of whether a piece still needs the step, however close
        it lies to the goal (:meth:`pasta.core.Skill.unfinished` with this goal; ``None``: the distance decides)."""

    @abstractmethod
    def should_stop(self, piece: np.ndarray, said: Stop | None, steps: int) -> Stop | None:
        """After env step number ``steps`` (1, 2, ...), with the piece now at ``piece (P, 3)`` and the
        controller having said ``said`` with that step's action: ``None`` goes on, a :class:`Stop` ends the step."""

    @abstractmethod
    def should_retry(self, pieces: int, expected: int, ended: Stop) -> bool:
        """After a step that ended with ``ended``: whether it visibly failed and runs once more, given the
        ``pieces`` now observed and the ``expected`` count after a successful step."""
