"""Tasks (seeded initial-state/goal generators with ground-truth skill chains), the skill-step
executor shared by generation, demonstrations, the oracle and plan execution, and the oracle.

    from pasta.tasks import get_task, run_skill
    task = get_task("crs")
    inst = task.instance(seed=1000)          # cached under ~/.cache/pasta/tasks
    sim = task.make_sim(); sim.set_state(inst.init)
"""

from pasta.tasks.base import (
    GroundTruthStep,
    Score,
    Task,
    TaskConfig,
    TaskInstance,
    cache_root,
    split_pieces,
    fixed_test_seeds,
    fixed_val_seeds,
)
from pasta.tasks.step import SkillRun, Trajectory, piece_indices, run_skill, skill_observation

__all__ = [
    "GroundTruthStep",
    "Score",
    "SkillRun",
    "Task",
    "TaskConfig",
    "TaskInstance",
    "Trajectory",
    "cache_root",
    "get_task",
    "piece_indices",
    "run_skill",
    "skill_observation",
    "split_pieces",
    "task_names",
    "fixed_test_seeds",
    "fixed_val_seeds",
]


def task_names() -> list[str]:
    """Names of the registered tasks."""
    from pasta.plugins import get_plugins

    return get_plugins().tasks.names()


def get_task(name: str, config=None, **overrides) -> Task:
    """Build the registered task ``name`` (unknown names list the known ones); ``overrides`` set config
    fields, typed values or strings (``distractors="4"``, as ``task.distractors=4`` on the command line);
    an unknown field names the task's settings and the closest one."""
    from dataclasses import asdict

    from pasta.config.overrides import build
    from pasta.plugins import get_plugins

    registry = get_plugins().tasks
    cfg = config if config is not None else registry.default_config(name)
    if overrides:
        cfg = build(type(cfg), {**asdict(cfg), **overrides}, command=f"task '{name}' (task.<setting>=)")
    return registry.create(name, cfg)
