"""pluggy hook specifications: how a plugin module registers skills, planners, encoders, cost models and tasks.

A plugin is a module named by an entry point in the ``pasta.plugins`` group. It implements any of the
hooks below with :data:`hookimpl`; each hook receives a ``register`` callable. Registration is cheap
metadata: the ``factory`` is a ``"module:attribute"`` string imported only when the plugin is built, so
listing plugins never imports torch or taichi.

Example (a third-party package's ``my_pkg/plugin.py``)::

    from pasta.core import SkillSpec
    from pasta.plugins import hookimpl

    @hookimpl
    def pasta_register_skills(register):
        register(spec=SkillSpec("pinch", n_in=2, n_out=1, tool="gripper"), factory="my_pkg.pinch:PinchSkill")
"""

from __future__ import annotations

from typing import Any, Protocol

import pluggy

PROJECT = "pasta"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


class RegisterSkill(Protocol):
    def __call__(self, *, spec: Any, factory: str, config: type | None = None, summary: str = "") -> None: ...


class RegisterComponent(Protocol):
    def __call__(self, *, name: str, factory: str, config: type | None = None, summary: str = "") -> None: ...


@hookspec
def pasta_register_skills(register: RegisterSkill) -> None:
    """Register skills: ``register(spec=SkillSpec(...), factory="pkg.mod:SkillClass", config=Dataclass)``.

    The factory must be a :class:`pasta.core.Skill` subclass whose ``spec`` equals the registered one.
    """


@hookspec
def pasta_register_planners(register: RegisterComponent) -> None:
    """Register planners: ``register(name=..., factory="pkg.mod:PlannerClass", config=PlannerConfigSubclass)``.

    The config must be a dataclass subclassing :class:`pasta.core.PluginConfig`; ``planner=NAME`` on the
    command line swaps it in as the ``planner`` section of the run config.
    """


@hookspec
def pasta_register_encoders(register: RegisterComponent) -> None:
    """Register entity encoders (:class:`pasta.core.Encoder` subclasses)."""


@hookspec
def pasta_register_cost_models(register: RegisterComponent) -> None:
    """Register cost models (:class:`pasta.core.CostModel` subclasses)."""


@hookspec
def pasta_register_tasks(register: RegisterComponent) -> None:
    """Register tasks (initial state and goal generators)."""
