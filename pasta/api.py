"""The Python surface of pasta: what ``import pasta`` gives (docs/python.md walks through it).

Shapes: a point cloud is a float ``(P, 3)`` array in the workspace frame (metres, y up, the unit cube);
latents are ``(K, D)`` torch tensors, one row per piece (entity). Every function takes the
:class:`~pasta.execute.session.Session` that :func:`load` returns: the task, the models, the planner and
every setting of the run config (``pasta config task=crs`` lists them).

>>> import pasta
>>> session = pasta.load("crs", execute={"controller": "heuristic"})
>>> sim, instance = pasta.instance(session, 1000)        # simulator at the instance's start, goal (G, 3)
>>> perceived = pasta.plan(session, sim.observe().dough, instance.goal)
>>> result = pasta.execute_plan(session, sim, perceived.plan, instance.goal)
>>> pasta.score(session, result.final_dough, instance).improvement   # normalised EMD improvement

This module sits on top of every layer; ``pasta/__init__`` loads it on first use of a name, so ``import
pasta`` and ``import pasta.core`` stay light (no torch, no taichi). No name here is also the name of a
subpackage (``pasta.execute``, ``pasta.tasks``, ``pasta.plugins`` are packages: importing one sets that
attribute of ``pasta``, which would hide a function of the same name).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from pasta.core.plan import Plan
from pasta.execute.episode import Perceived
from pasta.execute.executor import ExecutionResult
from pasta.execute.session import EpisodeOutcome, Session
from pasta.io import RunLogger, RunReader
from pasta.tasks.base import Score, TaskInstance

__all__ = ["EpisodeOutcome", "ExecutionResult", "Perceived", "Plan", "RunLogger", "RunReader", "Score", "Session",
           "TaskInstance", "execute_plan", "instance", "load", "perceive", "plan", "registry", "score", "task_names"]


def load(task: str, overrides: Sequence[str] = (), **settings: Any) -> Session:
    """The task ``task`` with a method's models, planner and controllers, from one resolved run config.

    Args:
        task: a registered task (:func:`task_names` lists them), e.g. ``"crs"``.
        overrides: ``key=value`` items, as on the command line (``["planner=sampling", "seed=3"]``).
        settings: the same as keywords, sections as dicts: ``execute={"controller": "learned"}``,
            ``models="my_models"`` (a ``pasta train`` root; default the shipped weights).

    Raises:
        ConfigError: an unknown key (with a suggestion) or a bad value.
    """
    from pasta.execute.session import build_session

    return build_session(task, overrides, **settings)


def instance(session: Session, seed: int) -> tuple[Any, TaskInstance]:
    """``(simulator, instance)``: the task instance of ``seed`` (generated and cached on first use; test configs
    are seeds 1000-1019) and a simulator set to its initial state. ``instance.init_points`` ``(P, 3)`` is the
    observed start, ``instance.goal`` ``(G, 3)`` the observed goal."""
    inst = session.task.instance(int(seed))
    sim = session.task.make_sim()
    sim.set_state(inst.init)
    return sim, inst


def perceive(session: Session, points: np.ndarray, *, seed: int = 0) -> tuple[list[np.ndarray], Any]:
    """``(pieces, latents)`` of a cloud ``points (P, 3)``: the pieces as ``perception.num_points`` resampled
    ``(num_points, 3)`` clouds and their latents ``(K, D)`` (``session.encoder``)."""
    from pasta.execute.episode import perceive as _perceive

    pieces, _labels, _cloud, latents = _perceive(_cloud_arg(points, "points"), session.encoder, session.perception,
                                                 seed=seed)
    return pieces, latents


def plan(session: Session, obs: np.ndarray, goal: np.ndarray, *, seed: int = 0, horizon: int | None = None,
         skeleton: Sequence[str] | None = None) -> Perceived:
    """Perceive ``obs (P, 3)`` and ``goal (G, 3)`` and plan with the session's planner (the path ``pasta plan``,
    ``pasta run`` and ``pasta eval`` take). ``.plan`` is the :class:`~pasta.core.Plan` (``.skills``,
    ``.summary()``, ``.to_json()``); ``.entities``, ``.labels`` and ``.latents`` are what was perceived.

    Raises:
        InputError: a malformed cloud, or pieces outside the models' training boxes.
        UnreachableGoalError: the goal holds far more or less dough than ``obs`` (``check.volume_ratio``).
    """
    return session.plan_clouds(_cloud_arg(obs, "obs"), _cloud_arg(goal, "goal"), seed=seed, horizon=horizon,
                               skeleton=skeleton)


def execute_plan(session: Session, sim: Any, plan: Plan, goal: np.ndarray, *, logger: RunLogger | None = None
            ) -> ExecutionResult:
    """Execute ``plan`` in ``sim`` with the session's controllers (``execute.controller``), step by step under
    the step monitor; ``.final_dough`` ``(P, 3)`` is the observed end, ``.steps`` what each step did. The
    session's ``disturb=`` and ``execute.loop=closed`` apply (``.decisions``, ``.plans``, ``.disturbance``).
    ``logger``: a :class:`RunLogger` that records the run (MCAP)."""
    from pasta.execute.executor import execute_plan as _execute_plan

    if not isinstance(plan, Plan):
        raise TypeError(f"plan must be a pasta.Plan (the .plan of pasta.plan(...)), got {type(plan).__name__}")
    goal = _cloud_arg(goal, "goal")
    seed = int(session.cfg.seed)
    return _execute_plan(sim, plan, skills={s.name: s for s in session.skills}, encoder=session.encoder,
                        goal=goal, cfg=session.exe, perception=session.perception,
                        emd_points=session.task.config.emd_points, emd_seed=session.task.config.emd_seed,
                        logger=logger, disturb=str(session.cfg.get("disturb", "")), seed=seed,
                        replan=session.replanner(goal, seed=seed) if session.exe.loop == "closed" else None)


def score(session: Session, final: np.ndarray, instance: TaskInstance) -> Score:
    """The task's score of the observed final dough ``final (P, 3)`` on ``instance``: ``.improvement``
    (normalised EMD improvement, 1 = the goal) and ``.success`` (above the task's threshold)."""
    return session.task.score(_cloud_arg(final, "final"), instance)


def task_names() -> list[str]:
    """The registered task names."""
    return sorted(registry().tasks.names())


def registry() -> Any:
    """The plugin registry (skills, planners, encoders, cost models, tasks), as ``pasta plugins`` lists it."""
    from pasta.plugins import get_plugins

    return get_plugins()


def _cloud_arg(points: Any, name: str) -> np.ndarray:
    from pasta.core.shapes import check_points

    return check_points(np.asarray(points), name)
