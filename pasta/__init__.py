"""pasta: planning with spatial and temporal abstraction over dough point clouds (PASTA, CoRL 2022).

The Python surface (docs/python.md)::

    import pasta
    session = pasta.load("crs")                              # task, models, planner, settings
    sim, instance = pasta.instance(session, 1000)            # simulator at the start; instance.goal (G, 3)
    perceived = pasta.plan(session, sim.observe().dough, instance.goal)
    result = pasta.execute_plan(session, sim, perceived.plan, instance.goal)
    pasta.score(session, result.final_dough, instance)       # .improvement, .success

The names come from :mod:`pasta.api` and are loaded on first use, so ``import pasta`` (and every
``pasta.<subpackage>``) stays light: no torch, no taichi until a model or the simulator is needed.
"""

from typing import Any

from pasta._version import __version__

#: the public names (:mod:`pasta.api`), loaded on first access
__all__ = ["EpisodeOutcome", "ExecutionResult", "Perceived", "Plan", "RunLogger", "RunReader", "Score", "Session",
           "TaskInstance", "execute_plan", "instance", "load", "perceive", "plan", "registry", "score", "task_names",
           "__version__"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        from pasta import api

        return getattr(api, name)
    raise AttributeError(f"module 'pasta' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
