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
from pasta.tasks.executor import SkillRun, Trajectory, piece_indices, run_skill, skill_observation

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
    """Build the registered task ``name`` (unknown names list the known ones); ``overrides`` set config fields."""
    from pasta.core.errors import ConfigError
    from pasta.plugins import get_plugins

    registry = get_plugins().tasks
    cfg = config if config is not None else registry.default_config(name)
    for key, value in overrides.items():
        if not hasattr(cfg, key):
            raise ConfigError(f"task '{name}' has no setting '{key}'")
        setattr(cfg, key, value)
    return registry.create(name, cfg)
