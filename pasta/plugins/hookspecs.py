"""pluggy hook specifications: how a plugin module registers skills, tools, planners, encoders, cost models and tasks.

A plugin is a module named by an entry point in the ``pasta.plugins`` group. It implements any of the
hooks below with :data:`hookimpl`; each hook receives a ``register`` callable. Registration is cheap
metadata: the ``factory`` is a ``"module:attribute"`` string imported only when the plugin is built, so
listing plugins never imports torch or taichi.

Example (a third-party package's ``my_pkg/plugin.py``)::

    from pasta.core import SkillSpec, ToolSpec
    from pasta.plugins import hookimpl

    @hookimpl
    def pasta_register_tools(register):  # geometry, action layout, parking pose: see pasta.core.ToolSpec
        register(spec=ToolSpec("gripper", description="two-finger parallel gripper", primitives=..., action=..., park=...))

    @hookimpl
    def pasta_register_skills(register):
        register(spec=SkillSpec("pinch", n_in=2, n_out=1, tool="gripper"), factory="my_pkg.pinch:PinchSkill")

Names are global per kind: registering a name another plugin already registered is refused at load time
(the built-in distribution's registration is kept; see :func:`pasta.plugins.registry.discover`), and a
skill whose tool no plugin registers is refused too. ``pasta plugins`` lists the refusals and exits 1.
"""

from __future__ import annotations

from typing import Any, Protocol

import pluggy

PROJECT = "pasta"
hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


class RegisterSkill(Protocol):
    def __call__(self, *, spec: Any, factory: str, config: type | None = None, summary: str = "") -> None: ...


class RegisterTool(Protocol):
    def __call__(self, *, spec: Any) -> None: ...


class RegisterComponent(Protocol):
    def __call__(self, *, name: str, factory: str, config: type | None = None, summary: str = "") -> None: ...


@hookspec
def pasta_register_skills(register: RegisterSkill) -> None:
    """Register skills: ``register(spec=SkillSpec(...), factory="pkg.mod:SkillClass", config=Dataclass)``.

    The factory must be a :class:`pasta.core.Skill` subclass whose ``spec`` equals the registered one.
    """


@hookspec
def pasta_register_tools(register: RegisterTool) -> None:
    """Register simulator tools: ``register(spec=ToolSpec(...))`` (:class:`pasta.core.ToolSpec`).

    Tools are data (geometry, action layout, parking pose), so there is no factory. Every skill's
    ``SkillSpec.tool`` must name a registered tool, or the skill is refused at load time.
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
    """Register tasks: ``register(name=..., factory="pkg.mod:TaskClass", config=Dataclass)``.

    The factory must be a :class:`pasta.core.Task` subclass whose ``name`` equals the registered one
    (initial state and goal generators with a ground-truth skill chain; see :mod:`pasta.core.task`).
    """
