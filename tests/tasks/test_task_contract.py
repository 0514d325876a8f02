"""The task contract (``pasta.core.Task``, :func:`check_task`, :class:`TaskContract`) on a toy task plugin
that needs no simulator, and the registry's check of task factories."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from pasta.core import PluginConfig, PluginValidationError, Task, TaskScore
from pasta.core.metrics import emd, normalized_improvement
from pasta.plugins import PluginInfo, hookimpl
from pasta.plugins.analytic import AnalyticPlugin
from pasta.plugins.checks import PluginConformanceError, check_task
from pasta.plugins.registry import discover
from pasta.plugins.testing import TaskContract


@dataclass
class ToyInstance:
    seed: int
    init: np.ndarray
    goal: np.ndarray
    skeleton: list[str]

    @property
    def init_points(self) -> np.ndarray:
        return self.init


@dataclass
class ToyConfig(PluginConfig):  # a task's settings are a group of the run config (task=NAME): a PluginConfig
    threshold: float = 0.8
    shift: float = 0.3


class ToyTask(Task):
    """Move a random blob by ``shift`` along x (the analytic ``move`` skill)."""

    name = "toy"
    skeleton = ("move",)

    def __init__(self, config: ToyConfig | None = None) -> None:
        self.config = config or ToyConfig()

    @property
    def threshold(self) -> float:
        return self.config.threshold

    def generate(self, seed, sim=None):
        init = np.random.default_rng(seed).random((200, 3)).astype(np.float32) * 0.1
        return ToyInstance(seed, init, init + np.float32([self.config.shift, 0, 0]), list(self.skeleton))

    def instance(self, seed, *, sim=None, cache=True):
        return self.generate(seed)

    def score(self, final_points, instance):
        e0, e1 = emd(instance.init_points, instance.goal, n=100), emd(np.asarray(final_points), instance.goal, n=100)
        ni = normalized_improvement(e0, e1)
        return TaskScore(e0, e1, ni, ni > self.threshold)

    def make_sim(self):
        raise NotImplementedError("the toy task runs no simulator")


class ToyPlugin:
    @hookimpl
    def pasta_register_tasks(self, register):
        register(name="toy", factory=f"{__name__}:ToyTask", config=ToyConfig, summary="toy task for contract tests")


PLUGINS = discover(extra={"analytic": AnalyticPlugin(), "toy": ToyPlugin()})


class TestToyTask(TaskContract):
    task_name = "toy"
    task_overrides = {"shift": 0.2}
    seed = 3

    def plugins(self):
        return PLUGINS


def test_check_task_names_what_is_wrong():
    skills = PLUGINS.skills

    class Unregistered(ToyTask):
        skeleton = ("move", "not_a_registered_skill")  # not "pinch": the example plugin registers that one

    with pytest.raises(PluginConformanceError, match=r"uses unregistered skills \['not_a_registered_skill'\]; registered: \[.*'move'"):
        check_task(Unregistered(), skills=skills)

    class NoMove(ToyTask):
        def generate(self, seed, sim=None):
            inst = super().generate(seed)
            inst.goal = inst.init.copy()
            return inst

    with pytest.raises(PluginConformanceError, match="the goal equals the initial dough"):
        check_task(NoMove(), skills=skills)

    class WrongChain(ToyTask):
        def generate(self, seed, sim=None):
            inst = super().generate(seed)
            inst.skeleton = ["split"]
            return inst

    with pytest.raises(PluginConformanceError, match=r"chain \['split'\] differs from the task's skeleton \['move'\]"):
        check_task(WrongChain(), skills=skills)

    class Shapes(ToyTask):
        def generate(self, seed, sim=None):
            inst = super().generate(seed)
            inst.goal = inst.goal[:-1]
            return inst

    with pytest.raises(PluginConformanceError, match=r"init_points \(200, 3\) and goal \(199, 3\)"):
        check_task(Shapes(), skills=skills)


def test_registry_requires_a_core_task_subclass():
    not_a_task = PluginInfo("task", "toy", "pasta.plugins.analytic:MoveSkill")
    with pytest.raises(PluginValidationError, match="not a pasta.core.Task subclass"):
        not_a_task.load()
    misnamed = PluginInfo("task", "other", f"{__name__}:ToyTask")
    with pytest.raises(PluginValidationError, match="ToyTask.name = 'toy' differs from the registered name"):
        misnamed.load()


def test_builtin_tasks_subclass_the_core_task():
    from pasta.plugins import get_plugins

    for name in get_plugins().tasks.names():
        cls = get_plugins().tasks.load(name)
        assert issubclass(cls, Task) and cls.name == name
